"""``candidates`` keeps every static scatterer inside the field of view, also far out near its
azimuth edge, where a grid cell's own angular margin (half its diagonal over its distance) is
smaller than the 0.05 rad the sector query adds (kills scatterers candidates 35: the query
narrowed by 0.05 rad instead of widened)."""

from __future__ import annotations

import numpy as np

from loaders.synthetic import scatterers as SC
from loaders.synthetic.raycast import Geometry
from loaders.synthetic.scenes import WALL
from loaders.synthetic.sensors import SENSORS

RADAR = SENSORS["radar-sparse"]  # +-75 deg azimuth, 0.5-100 m


def test_far_points_just_inside_the_azimuth_edge_are_candidates():
    # 50-98 m out at 73-74.9 deg on both sides: inside the field of view, facing the sensor
    ranges = np.arange(50.0, 99.0, 4.0)
    az_deg = np.array([73.0, 73.5, 74.0, 74.5, 74.9])
    pts = np.array([[r * np.cos(np.radians(s * a)), r * np.sin(np.radians(s * a)), 0.0]
                    for r in ranges for a in az_deg for s in (1.0, -1.0)])
    normals = -pts / np.linalg.norm(pts, axis=1, keepdims=True)  # each faces the sensor
    b = SC._Builder(np.random.default_rng(0))
    b.add(pts, normals, rcs=(0.0, 1.0), material=WALL)
    sc = b.build()
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    assert sorted(cand["ids"].tolist()) == list(range(len(pts)))
