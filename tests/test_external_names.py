"""bench.runs.external.names: a ``bench score`` run's name is one path component and neither a
harness method's name nor a harness run folder's; its folder is taken when free or holding an
external run, a harness run only when asked (--replace-run), a folder of other files never."""

import pytest

from bench.runs.external.names import check_name, check_run_folder
from loaders.errors import DataError


@pytest.mark.parametrize("name", ["my-odometry", "icp-p2p-ext", "Xodo", "a.b", "...",
                                  "doppler_seedling", "kiss-icp_seed2", "x y"])
def test_a_name_of_its_own_is_taken_as_it_is(name):
    assert check_name(name) == name


@pytest.mark.parametrize("name", ["", "   "])
def test_no_name_is_refused_asking_for_one(name):
    with pytest.raises(DataError) as err:
        check_name(name)
    assert str(err.value).startswith("--name: give the external method a name (e.g. --name ")


@pytest.mark.parametrize("name", ["a/b", "../../outside", "a\\b", "a\0b", ".", "..", " a", "a ",
                                  "a\n"])
def test_a_name_that_is_not_one_path_component_is_refused(name):
    with pytest.raises(DataError) as err:
        check_name(name)
    msg = str(err.value)
    assert msg.startswith(f"--name {name!r}: expected one path component (no '/', '\\', "
                          "surrounding spaces")
    assert msg.endswith("the run's folder under RESULTS_DIR/SEQUENCE/")


def test_a_harness_methods_name_is_refused_naming_one_that_would_do():
    with pytest.raises(DataError) as err:
        check_name("icp-p2p")
    msg = str(err.value)
    assert msg.startswith("--name 'icp-p2p' is a method of the harness; an external run needs a "
                          "name of its own (e.g. icp-p2p-ext)")
    assert msg.endswith("so it never replaces that run")


@pytest.mark.parametrize("name, method, how", [("icp-p2p_seed", "icp-p2p", "with"),
                                               ("doppler_noseed", "doppler", "without"),
                                               ("kiss-icp_seed", "kiss-icp", "with")])
def test_a_harness_run_folders_name_is_refused_saying_which_run(name, method, how):
    with pytest.raises(DataError) as err:
        check_name(name)
    msg = str(err.value)
    assert msg.startswith(f"--name {name!r} is the run folder of the harness's {method} run "
                          f"{how} its seed; an external run needs a name of its own "
                          f"(e.g. {name}-ext)")
    assert msg.endswith("so it never replaces that run")


# --- the run's folder -------------------------------------------------------------------------

def test_a_missing_or_empty_folder_is_free(tmp_path):
    assert check_run_folder(tmp_path / "new", replace_run=False) == ""
    (tmp_path / "empty").mkdir()
    assert check_run_folder(tmp_path / "empty", replace_run=False) == ""


@pytest.mark.parametrize("config", ["identity:\n  kind: external\n",
                                    "external:\n  trajectory: a.tum\n",
                                    "identity: {kind: harness}\nexternal: {trajectory: a.tum}\n"])
def test_an_external_run_is_bench_scores_own(tmp_path, config):
    (tmp_path / "config.yaml").write_text(config)
    assert check_run_folder(tmp_path, replace_run=False) == ""


def test_a_folder_of_other_files_is_refused_even_when_replacing(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    for replace in (False, True):
        with pytest.raises(DataError) as err:
            check_run_folder(tmp_path, replace_run=replace)
        msg = str(err.value)
        assert msg.startswith(f"{tmp_path} holds files that are no run; bench score writes "
                              "only into a new folder or one of its own runs")
        assert msg.endswith("choose another --name or --out")


@pytest.mark.parametrize("files, method", [
    ({"config.yaml": "identity: {kind: harness}\nmethod: {name: icp-p2p}\n"}, "icp-p2p"),
    ({"config.yaml": "method: {name: gicp}\nexternal: not-a-mapping\n"}, "gicp"),
    ({"metrics.json": "{}"}, "?"),  # a run's record without its config
    ({"failed.json": "{}"}, "?"),
    ({"config.yaml": "identity: [\n"}, "?"),  # unreadable: a run all the same
    ({"config.yaml": "- a\n- b\n"}, "?"),  # no mapping
    ({"config.yaml": ""}, "?"),
    ({"config.yaml": "method: {seed: true}\n"}, "?"),
    # no mapping where a run's config has one (by hand, another tool's): a run of unknown
    # method, not an AttributeError
    ({"config.yaml": "identity: null\nmethod: {name: icp-p2p}\n"}, "icp-p2p"),
    ({"config.yaml": "identity: external\nmethod: sgd\n"}, "?"),
    ({"config.yaml": "identity: [kind, external]\nmethod: [name, gicp]\n"}, "?"),
])
def test_a_harness_run_is_replaced_only_when_asked(tmp_path, files, method):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    what = f"a harness run (method {method})"
    with pytest.raises(DataError) as err:
        check_run_folder(tmp_path, replace_run=False)
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path} holds {what}; bench score does not replace it: choose "
                          "another --name")
    assert msg.endswith("(or --replace-run to replace that run)")
    assert check_run_folder(tmp_path, replace_run=True) == what


def test_an_unreadable_config_is_a_run_of_unknown_method(tmp_path):
    (tmp_path / "config.yaml").mkdir()  # reading it fails (OSError)
    assert check_run_folder(tmp_path, replace_run=True) == "a harness run (method ?)"
