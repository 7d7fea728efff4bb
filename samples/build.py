"""Rebuild ``ntu4dradlm-loop1.h5`` from the published frames (run from the repository root):

    python samples/build.py PATH/TO/ntu4dradlm-loop1-long

PATH holds ``frames/frame_001.npy ... frame_250.npy`` (+ ``_dop.npy``) and ``gt_tum.txt`` as in
the example folder of github.com/Tars0523/Doppler_Correspondence. The values are float32 in the
source (stored there as float64), so the store holds them exactly.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from loaders.npy_frames import NpyFramesSequence
from loaders.store import write_store

PERIOD_S = 1.0 / 12.0  # the Oculii Eagle's scan period; the TUM stamps are not the radar clock
OUT = Path(__file__).resolve().parent / "ntu4dradlm-loop1.h5"


def main(source: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the ~1 in 6 repeated GT rows are documented
        seq = NpyFramesSequence(source, period_s=PERIOD_S, name="ntu4dradlm-loop1")
        seq.provenance = {
            "loader": "npy-frames", "frames": len(seq), "period_s": PERIOD_S,
            "gt_association": "order", "repeated_gt_poses": seq.repeated_gt_poses,
            "source": "NTU4DRadLM loop 1 (Oculii Eagle 4D radar), frames 1-250 as published "
                      "in github.com/Tars0523/Doppler_Correspondence (MIT); see samples/README.md",
            "sensor_class": "Semi-Dense 4D Radar",
        }
        write_store(seq, OUT, compression="gzip")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main(sys.argv[1])
