"""Residue survivors of methods.dicp: the pair gate of the several-thread search is inclusive
(a source point exactly at the gate has its pair), as the one-thread search's."""

import numpy as np
import pytest

from loaders.scan import Scan
from methods.dicp import Dicp


def _grid_scans():
    """A target of 3 x 3 x 3 integer grid points (1 m apart, 5 m ahead of the sensor); the
    source: the same points plus one 0.5 m from the corner (5, -1, -1) along -x, farther
    than 0.5 m from every other grid point (exactly representable: its squared distance is
    0.25). Doppler zero: no motion, as the identity start says."""
    g = np.arange(-1.0, 2.0)
    grid = np.array([[5.0 + x, y, z] for x in g for y in g for z in g])
    extra = np.array([[4.5 - 1.0, -1.0, -1.0]])
    src = np.vstack([grid, extra])
    return Scan(0.0, src, np.zeros(len(src))), Scan(0.1, grid, np.zeros(len(grid)))


@pytest.mark.parametrize("threads", [1, 2])
def test_a_point_exactly_at_the_gate_is_paired(threads):
    # kills DICP _iterate 71 (several threads: the gate test made strict): 27 points at
    # distance 0 and one at exactly 0.5 m = the gate; with one step the pairs counted are
    # those of the start, all 28 of them
    dicp = Dicp(max_correspondence_m=0.5, max_iterations=1, downsample=1, num_threads=threads)
    source, target = (dicp.preprocess(s) for s in _grid_scans())
    result = dicp.register(source, target, np.eye(4))
    assert result.correspondences == 28
