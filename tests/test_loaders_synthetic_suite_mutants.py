"""loaders/synthetic/suite.py, in-process: the suites' names and entries, the entry hash, the
generator an entry makes, and ``ensure_suite`` (which stores it writes, with which writer, and
how it reports progress)."""

import hashlib
import json

import pytest

from loaders.errors import DataError
from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR
from loaders.store import StoreSequence, write_store
from loaders.synthetic import suite
from loaders.synthetic.codehash import current_code_hash
from loaders.synthetic.suite import SuiteEntry, ensure_suite, store_is_current, suite_entries

TINY = SuiteEntry("tiny", "Tiny", SPARSE_RADAR, "campus", "radar-sparse", 2, 7,
                  {"points": 50}, noise=False)


def test_unknown_suite_names_itself_and_the_known_ones():
    with pytest.raises(DataError, match=r"unknown synthetic suite 'nope'; known: "
                                        r"synthetic-paper, synthetic-clean, synthetic-ci$"):
        suite_entries("nope")


def test_suite_entries_is_a_copy():
    entries = suite_entries("synthetic-ci")
    entries.clear()
    assert len(suite_entries("synthetic-ci")) == 5


def test_paper_suite_names_classes_and_sizes():
    paper = {e.name: e for e in suite_entries("synthetic-paper")}
    assert list(paper) == ["Campus1", "Campus2", "Loop1_0", "Loop1_1", "Loop1_2", "Loop1_3",
                           "Loop1_4", "StraightWall", "CurvedWall", "Tunnel_Empty",
                           "Tunnel_Vehicles"]
    assert {paper[n].klass for n in ("Campus1", "Campus2")} == {SPARSE_RADAR}
    assert {paper[f"Loop1_{i}"].klass for i in range(5)} == {SEMI_DENSE_RADAR}
    assert {paper[n].klass for n in ("StraightWall", "CurvedWall", "Tunnel_Empty",
                                     "Tunnel_Vehicles")} == {DENSE_LIDAR}
    assert paper["Loop1_4"].options == {"gt": "ntu4dradlm", "uturn": True}
    assert paper["Tunnel_Vehicles"].options == {"sweep": True, "rib_spacing": 0,
                                                "one_lane": True}
    assert paper["StraightWall"].options == {"speed": (16.5, 17.3)}
    # seeds all different, so no two sequences are the same
    assert len({e.seed for e in paper.values()}) == 11
    assert all(e.imitates and e.noise for e in paper.values())


def test_clean_suite_drops_only_the_gt_pipeline():
    paper, clean = suite_entries("synthetic-paper"), suite_entries("synthetic-clean")
    assert [e.name for e in clean] == [e.name for e in paper]
    for p, c in zip(paper, clean, strict=True):
        assert "gt" not in c.options
        assert c.options == {k: v for k, v in p.options.items() if k != "gt"}
        assert (c.seed, c.frames, c.scene, c.sensor) == (p.seed, p.frames, p.scene, p.sensor)
    assert "gt" in paper[0].options  # the paper entry itself is unchanged


def test_ci_suite_entries():
    ci = {e.name: e for e in suite_entries("synthetic-ci")}
    assert list(ci) == ["ci-sparse", "ci-semidense", "ci-uturn", "ci-tunnel", "ci-wall"]
    assert ci["ci-uturn"].options == {"uturn": True}
    assert ci["ci-tunnel"].options == ci["ci-wall"].options == {"points": 8000}
    assert all(not e.imitates for e in ci.values())


def test_entry_hash_is_sha256_of_sorted_params_and_code():
    code = "abc"
    params = {"name": "tiny", "display": "Tiny", "klass": SPARSE_RADAR, "scene": "campus",
              "sensor": "radar-sparse", "frames": 2, "seed": 7, "options": {"points": 50},
              "noise": False, "imitates": "", "generator_code": code}
    text = json.dumps(params, sort_keys=True)
    assert TINY.entry_hash(code) == hashlib.sha256(text.encode()).hexdigest()[:16]
    assert TINY.entry_hash() == TINY.entry_hash(current_code_hash())
    assert TINY.entry_hash("abd") != TINY.entry_hash(code)


def test_sequence_meta_with_and_without_imitates():
    seq = TINY.sequence("my-suite")
    assert seq.name == "tiny"
    prov = seq.provenance
    assert prov["suite"] == "my-suite"
    assert prov["display_name"] == "Tiny"
    assert prov["class"] == SPARSE_RADAR
    assert prov["suite_entry_hash"] == TINY.entry_hash()
    assert prov["generator_code_hash"] == current_code_hash()
    assert "imitates" not in prov and "notice" not in prov
    imit = SuiteEntry("t2", "T2", SPARSE_RADAR, "campus", "radar-sparse", 2, 7,
                      {"points": 50}, noise=False, imitates="X")
    prov2 = imit.sequence().provenance
    assert prov2["suite"] == ""
    assert prov2["imitates"] == "X"
    assert prov2["notice"] == ("synthetic data imitating X; made by this repository's "
                               "generator, not the paper's data")


@pytest.fixture
def tiny_suite(monkeypatch):
    monkeypatch.setitem(suite.SUITES, "tiny-suite", [TINY])
    return "tiny-suite"


def test_ensure_suite_writes_with_the_writer_then_keeps_a_current_store(tmp_path, tiny_suite):
    written, seen = [], []

    def writer(seq, path, progress):
        written.append((seq.name, path))
        return write_store(seq, path, progress)

    paths = ensure_suite(tiny_suite, tmp_path, lambda *a: seen.append(a), writer=writer)
    target = tmp_path / "tiny-suite" / "tiny.h5"
    assert paths == [target]
    assert written == [("tiny", target)]
    assert seen == [("tiny", 1, 2), ("tiny", 2, 2)]
    store = StoreSequence(target)
    try:
        assert store.provenance["suite"] == "tiny-suite"
    finally:
        store.close()
    assert store_is_current(target, TINY)
    seen.clear()
    assert ensure_suite(tiny_suite, str(tmp_path), lambda *a: seen.append(a),
                        writer=writer) == [target]
    assert len(written) == 1  # not rewritten
    assert seen == [("tiny", 2, 2)]


def test_ensure_suite_without_progress_passes_none(tmp_path, tiny_suite):
    got = []
    ensure_suite(tiny_suite, tmp_path, writer=lambda seq, path, cb: got.append(cb))
    assert got == [None]


def test_default_writer_is_write_store(tmp_path, tiny_suite):
    (path,) = ensure_suite(tiny_suite, tmp_path)
    assert store_is_current(path, TINY)


def test_store_is_current_false_cases(tmp_path):
    missing = tmp_path / "none.h5"
    assert not store_is_current(missing, TINY)
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not a store")
    assert not store_is_current(junk, TINY)
    other = SuiteEntry("tiny", "Tiny", SPARSE_RADAR, "campus", "radar-sparse", 2, 8,
                       {"points": 50}, noise=False)
    path = write_store(other.sequence("s"), tmp_path / "other.h5")
    assert store_is_current(path, other)
    assert not store_is_current(path, TINY)


def test_sequence_passes_seed_noise_and_options():
    noisy = SuiteEntry("n", "N", SPARSE_RADAR, "campus", "radar-sparse", 2, 9, {"points": 50})
    seq = noisy.sequence()
    assert (seq.seed, seq.noise) == (9, True)
    assert seq.options["points"] == 50
    quiet = TINY.sequence()
    assert (quiet.seed, quiet.noise) == (7, False)


def test_clean_entry_drops_gt_and_keeps_the_rest():
    entry = SuiteEntry("a", "A", SPARSE_RADAR, "campus", "radar-sparse", 3, 5,
                       {"gt": "campus", "uturn": True}, imitates="I")
    clean = suite._clean(entry)
    assert clean.options == {"uturn": True}
    assert (clean.name, clean.seed, clean.frames, clean.imitates) == ("a", 5, 3, "I")
    assert entry.options == {"gt": "campus", "uturn": True}


def test_entry_hash_takes_options_json_cannot_encode():
    from pathlib import Path

    entry = SuiteEntry("p", "P", SPARSE_RADAR, "campus", "radar-sparse", 2, 1,
                       {"path": Path("x")})
    as_text = SuiteEntry("p", "P", SPARSE_RADAR, "campus", "radar-sparse", 2, 1, {"path": "x"})
    assert entry.entry_hash("c") == as_text.entry_hash("c")


def test_suite_adds_exactly_its_own_provenance_keys():
    from loaders.synthetic.generate import SyntheticSequence

    plain = SyntheticSequence("campus", "radar-sparse", 2, 7, False, name="tiny", points=50)
    added = set(TINY.sequence("s").provenance) - set(plain.provenance)
    assert added == {"suite", "display_name", "class", "suite_entry_hash"}
