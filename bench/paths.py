"""Every path the commands read from the repository, in one place (relative to the checkout,
never outside it)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
DATASET_CONFIGS = CONFIGS / "datasets"
EXPERIMENTS = CONFIGS / "experiments"
SPLITS = CONFIGS / "splits.yaml"
CI_EXPERIMENT = EXPERIMENTS / "ci.yaml"
CI_BASELINE = CONFIGS / "ci" / "baseline.json"
#: the paper's Tables III-V as CSV (paper/README.md)
PAPER_TABLE3 = ROOT / "paper" / "table3.csv"
PAPER_TABLE4_5 = ROOT / "paper" / "table4_5_ape.csv"
#: the vendored real radar frames (samples/README.md): NTU4DRadLM loop 1, frames 1-250
REAL_SAMPLE = ROOT / "samples" / "ntu4dradlm-loop1.h5"
#: frames of REAL_SAMPLE that form the 60-frame sample of earlier versions
REAL_SAMPLE_60 = (0, 60)
