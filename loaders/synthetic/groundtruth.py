"""Ground-truth pipelines: the ground truth a synthetic sequence reports, made from the exact
motion the way the imitated dataset's ground truth was made.

A synthetic sequence knows its exact sensor pose ``T_world_sensor`` at every instant. A real
dataset's ground truth is a different sensor's estimate, sampled at its own rate and given to
the scans by some association; the paper's errors contain that pipeline's errors (see
loaders/synthetic/README.md). Pipelines (option ``gt`` of ``SyntheticSequence``):

- ``exact``: the exact ``T_world_sensor`` at the scan stamps (CARLA: the simulator's own poses).
- ``ntu4dradlm``: NTU4DRadLM's pseudo ground truth (R2LIVE) as the paper's reference code gives
  it to the Eagle scans: poses of the GT body frame (rotated against the radar by
  ``NTU_R_GT_SENSOR_DEG``, offset by ``NTU_T_GT_SENSOR_M``), sampled at 10 Hz on their own clock
  and given to each scan by the nearest GT stamp. With 12 Hz scans about one row in six repeats
  the previous one, and a scan's GT pose is up to 50 ms off its stamp.
- ``campus``: a NovAtel GNSS/INS (Campus dataset): the sensor's pose sampled at 50 Hz with the
  receiver's noise (``CAMPUS_POSITION_SIGMA_M``, ``CAMPUS_ATTITUDE_SIGMA_DEG``, white per sample:
  an upper bound of the smooth INS output), then interpolated at the scan stamps, as this
  harness's Campus loader does with the real 50 Hz GT. Positions are in a local east-north-up
  frame (UTM after removing the first position: a rigid change of world frame, invisible to
  relative errors; the grid scale factor, within 4e-4 of 1, is ignored).

Every pipeline returns a ``Trajectory`` with one pose per scan stamp (``T_world_sensor`` as the
dataset's ground truth claims it). Deterministic from the seed given to ``ground_truth``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from loaders.scan import Trajectory
from loaders.se3 import inv_T, make_T

#: NTU4DRadLM: rotation of the GT body frame against the radar, R_gt_sensor = Rz(yaw) Ry(pitch)
#: Rx(roll) [deg], measured with ``bench calibrate`` on the vendored real loop-1 sample's frames
#: 0-124 (pitch and yaw from the Doppler ego velocity, roll from the road plane) before its
#: block bootstrap and its second-order fix; the same frames give today roll -1.26 [-2.58,
#: +0.07], pitch -2.58 [-2.95, -2.20], yaw -0.28 [-0.41, -0.15] deg (95 %, docs/doppler-ego.md),
#: which contain these values. Kept so the synthetic suites' data do not change;
#: shared/REFERENCE.md: "pitched about 1.9 deg".
NTU_R_GT_SENSOR_DEG = {"roll": -1.24, "pitch": -2.58, "yaw": -0.19}
#: NTU4DRadLM: the radar's origin in the GT body frame [m] (configs/datasets/Loop1_0.yaml,
#: T_gtbody_radar, from public SLAM code; unconfirmed)
NTU_T_GT_SENSOR_M = (0.296, -0.130, -0.005)
#: NTU4DRadLM ground-truth rate [Hz] (the reference code's example GT: 10 Hz rows given to 12 Hz
#: frames by nearest neighbour; shared/REFERENCE.md)
NTU_RATE_HZ = 10.0
#: Campus GNSS/INS output rate [Hz] (shared/REFERENCE.md: NovAtel GNSS/INS in UTM at 50 Hz)
CAMPUS_RATE_HZ = 50.0
#: Campus GNSS/INS position noise per axis [m]: NovAtel CPT7 RTK position accuracy
#: "1 cm + 1 ppm RMS" (docs.novatel.com, CPT7 performance specifications)
CAMPUS_POSITION_SIGMA_M = 0.01
#: Campus GNSS/INS attitude noise per axis [deg]: NovAtel CPT7 dual-antenna (ALIGN) heading
#: accuracy at a 2 m baseline, 0.08 deg (same page); used for roll and pitch too (an INS's roll
#: and pitch are at least as good as its heading: an upper bound)
CAMPUS_ATTITUDE_SIGMA_DEG = 0.08

PoseFn = Callable[[np.ndarray], np.ndarray]


def ntu_T_gt_sensor() -> np.ndarray:
    """T_gtbody_sensor of the NTU pipeline (4, 4)."""
    a = NTU_R_GT_SENSOR_DEG
    R = Rotation.from_euler("ZYX", [a["yaw"], a["pitch"], a["roll"]], degrees=True).as_matrix()
    return make_T(R, np.array(NTU_T_GT_SENSOR_M))


def gt_clock(t_first: float, t_last: float, rate_hz: float, phase_s: float) -> np.ndarray:
    """Stamps of a GT clock at ``rate_hz`` with ``phase_s`` (in [0, 1 / rate_hz)), one step
    beyond [t_first, t_last] on both sides."""
    step = 1.0 / rate_hz
    k0 = int(np.floor((t_first - phase_s) / step)) - 1
    k1 = int(np.ceil((t_last - phase_s) / step)) + 1
    return phase_s + step * np.arange(k0, k1 + 1)


def nearest_sample(t_gt: np.ndarray, t_scan: np.ndarray) -> np.ndarray:
    """Index of the nearest GT stamp to each scan stamp (ties to the earlier one)."""
    right = np.clip(np.searchsorted(t_gt, t_scan), 1, len(t_gt) - 1)
    left = right - 1
    return np.where(t_scan - t_gt[left] <= t_gt[right] - t_scan, left, right)


def exact(pose_at: PoseFn, t_scan: np.ndarray, stamps: np.ndarray,
          rng: np.random.Generator) -> Trajectory:
    """The exact T_world_sensor at the scan stamps."""
    return Trajectory(stamps, pose_at(t_scan))


def ntu4dradlm(pose_at: PoseFn, t_scan: np.ndarray, stamps: np.ndarray,
               rng: np.random.Generator) -> Trajectory:
    """GT body poses at 10 Hz (random clock phase), nearest-sampled at the scan stamps."""
    t_gt = gt_clock(t_scan[0], t_scan[-1], NTU_RATE_HZ, rng.uniform(0.0, 1.0 / NTU_RATE_HZ))
    idx = nearest_sample(t_gt, t_scan)
    T_sensor_gt = inv_T(ntu_T_gt_sensor())
    return Trajectory(stamps, pose_at(t_gt[idx]) @ T_sensor_gt)


def campus(pose_at: PoseFn, t_scan: np.ndarray, stamps: np.ndarray,
           rng: np.random.Generator) -> Trajectory:
    """Sensor poses at 50 Hz (random clock phase) with GNSS/INS noise, interpolated at the scan
    stamps."""
    t_gt = gt_clock(t_scan[0], t_scan[-1], CAMPUS_RATE_HZ,
                    rng.uniform(0.0, 1.0 / CAMPUS_RATE_HZ))
    poses = pose_at(t_gt)
    n = len(t_gt)
    noise_R = Rotation.from_rotvec(
        rng.normal(0.0, np.radians(CAMPUS_ATTITUDE_SIGMA_DEG), (n, 3))).as_matrix()
    poses[:, :3, :3] = poses[:, :3, :3] @ noise_R
    poses[:, :3, 3] += rng.normal(0.0, CAMPUS_POSITION_SIGMA_M, (n, 3))
    shift = stamps[0] - t_scan[0]  # GT clock stamps on the scans' clock
    return Trajectory(t_gt + shift, poses).interpolate(stamps, name="campus GT")


PIPELINES: dict[str, Callable[..., Trajectory]] = {
    "exact": exact, "ntu4dradlm": ntu4dradlm, "campus": campus}
DESCRIPTIONS = {
    "exact": "exact T_world_sensor at the scan stamps (CARLA)",
    "ntu4dradlm": "NTU4DRadLM-style: GT body frame tilted against the radar, 10 Hz, "
                  "nearest-matched to the scans (repeated rows)",
    "campus": "Campus-style GNSS/INS: 50 Hz with RTK-grade noise, interpolated at the scans",
}


def ground_truth(pipeline: str, pose_at: PoseFn, t_scan: np.ndarray, stamps: np.ndarray,
                 rng: np.random.Generator) -> Trajectory:
    """The ground truth of pipeline ``pipeline`` (see the module docstring): ``pose_at(t)`` is
    the exact T_world_sensor (N, 4, 4) at motion times t [s]; ``t_scan`` the scans' motion
    times, ``stamps`` their stamps (same length)."""
    if pipeline not in PIPELINES:
        raise ValueError(f"unknown ground-truth pipeline {pipeline!r}; known: "
                         f"{', '.join(PIPELINES)}")
    return PIPELINES[pipeline](pose_at, np.asarray(t_scan, float), np.asarray(stamps, float),
                               rng)


def pipeline_params(pipeline: str) -> dict:
    """The constants of ``pipeline`` for a store's provenance."""
    if pipeline == "ntu4dradlm":
        return {"rate_hz": NTU_RATE_HZ, "R_gt_sensor_deg": dict(NTU_R_GT_SENSOR_DEG),
                "t_gt_sensor_m": list(NTU_T_GT_SENSOR_M), "association": "nearest"}
    if pipeline == "campus":
        return {"rate_hz": CAMPUS_RATE_HZ, "position_sigma_m": CAMPUS_POSITION_SIGMA_M,
                "attitude_sigma_deg": CAMPUS_ATTITUDE_SIGMA_DEG, "association": "interpolate"}
    return {}
