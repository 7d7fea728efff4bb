"""``bench convert LOADER`` (bench/data/convert.py ``loader_command``), second round: the
options model's own refusal as the command words it, a loader of several inputs, the
ground-truth warning naming the loader's options, and ``--stride``. A probe loader defined here
(registered nowhere: a ``LoaderEntry`` pointing at this module) records what the command passes
it and returns a small in-memory sequence."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import Field
from typer.testing import CliRunner

from bench.cli import app
from bench.data.convert import loader_command
from conftest import constant_twist_sequence
from loaders.errors import DataError, GroundTruthWarning
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.registry import LoaderEntry
from loaders.scan import MemorySequence
from loaders.store import StoreSequence

runner = CliRunner()


class ProbeOptions(LoaderOptions):
    """Options of the probe loader: a ground-truth file, as real loaders have."""

    gt: Path | None = Field(None, description="ground-truth file")


class ProbeLoader(OpensFromOptions, MemorySequence):
    """A loader of several inputs that records the paths it is opened with."""

    Options = ProbeOptions
    inputs = "probe files"
    many_inputs = True
    opened: list[list[Path]] = []

    @classmethod
    def open(cls, paths, options):
        cls.opened.append(list(paths))
        seq = constant_twist_sequence(n_frames=5, n_points=40)
        if options.gt is None:
            seq.ground_truth = None
        return seq


PROBE = LoaderEntry("probe", "a probe loader", __name__, "ProbeLoader")


def convert_probe(args: list[str]) -> None:
    loader_command(PROBE).main(args, standalone_mode=False)


def inputs(tmp_path, n=2) -> list[Path]:
    paths = [tmp_path / f"part{i}.bin" for i in range(n)]
    for p in paths:
        p.write_bytes(b"x")
    return paths


def test_the_options_model_refusal_names_the_command_and_the_flag(tmp_path):
    """loader_command 73/74/77/78: 0.5 is inside the command line's range for a sign (-1..1),
    so rosbag's Options model refuses it, and the message names the command and the flag."""
    bag = tmp_path / "x.bag"
    bag.write_bytes(b"")
    res = runner.invoke(app, ["convert", "rosbag", str(bag), "--doppler-sign", "0.5",
                              "--out", str(tmp_path / "o.h5")])
    assert isinstance(res.exception, DataError)
    assert str(res.exception) == ("bench convert rosbag:\n  --doppler-sign: doppler_sign must "
                                  "be +1 or -1, got 0.5")
    assert not (tmp_path / "o.h5").exists()


def test_a_loader_of_several_inputs_gets_them_all_in_order(tmp_path):
    """loader_command 80/82: the INPUT... paths reach the loader as one list of paths."""
    paths = inputs(tmp_path, 3)
    gt = tmp_path / "gt.txt"
    gt.write_text("0 0 0 0 0 0 0 1\n")
    out = tmp_path / "o.h5"
    convert_probe([*map(str, paths), "--gt", str(gt), "--out", str(out)])
    assert ProbeLoader.opened[-1] == paths
    st = StoreSequence(out)
    assert len(st) == 5
    st.close()


def test_no_ground_truth_warns_naming_the_gt_option(tmp_path):
    """loader_command 105: the warning names the loader's own ground-truth flag."""
    with pytest.warns(GroundTruthWarning, match=r"scores none \(give it with --gt\)"):
        convert_probe([*map(str, inputs(tmp_path)), "--out", str(tmp_path / "o.h5")])


def test_stride_keeps_every_kth_frame(tmp_path):
    """loader_command 121: --stride 2 of 5 frames 0.1 s apart keeps frames 0, 2, 4."""
    gt = tmp_path / "gt.txt"
    gt.write_text("0 0 0 0 0 0 0 1\n")
    out = tmp_path / "o.h5"
    convert_probe([*map(str, inputs(tmp_path)), "--gt", str(gt), "--stride", "2",
                   "--out", str(out)])
    st = StoreSequence(out)
    np.testing.assert_allclose(st.stamps, [0.0, 0.2, 0.4], atol=1e-9)
    st.close()


def test_a_loader_without_a_layout_has_no_layout_paragraph():
    """loader_command 129/130: the help is the description and the inputs, nothing after."""
    command = loader_command(PROBE)
    assert command.help == "a probe loader.\n\nINPUT: probe files."
    params = {p.name: p for p in command.params}
    assert params["inputs"].metavar == "INPUT..." and params["inputs"].nargs == -1
