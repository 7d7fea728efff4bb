"""False alarms and detections of ``bench inspect``'s data checks other than the GT clock
(``bench.data.inspection.inspect_sequence``): the Doppler sign check, the Doppler kind check,
the height (elevation sign) check and the ground-truth sanity findings, on the vendored
NTU4DRadLM sample (``python -m bench.studies.inspect_checks_study``).

Correct inputs: the sample whole, its halves and 100-frame windows every 50 frames. Faults, on
the same pieces: the Doppler negated (the sign check must say FLIPPED), the Doppler replaced by
ego-compensated values (about 0 m/s on a static world: the kind check must measure
ego-compensated, disagreeing with the declared radial), the points mirrored in z (the height
check must find the densest layer above the sensor). Nothing here tuned these checks.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from bench.data.inspection import inspect_sequence
from loaders.scan import FrameRange, Sequence
from loaders.store import StoreSequence

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "ntu4dradlm-loop1.h5"


class Altered(Sequence):
    """Another sequence's scans through ``change`` (a fault), same stamps and ground truth."""

    def __init__(self, base: Sequence, change):
        self.base, self.change = base, change
        self.name, self.sensor = base.name, base.sensor
        self.ground_truth, self.provenance = base.ground_truth, base.provenance

    def __len__(self) -> int:
        return len(self.base)

    def scan(self, index: int):
        return self.change(self.base.scan(index))

    @property
    def stamps(self) -> np.ndarray:
        return self.base.stamps


def negated(scan):
    return replace(scan, doppler=-scan.doppler)


def compensated(scan):
    rng = np.random.default_rng(int(scan.stamp * 1000))
    return replace(scan, doppler=rng.normal(0.0, 0.05, len(scan.doppler)))


def mirrored(scan):
    p = scan.points.copy()
    p[:, 2] *= -1
    return replace(scan, points=p)


FAULTS = {"Doppler negated": (negated, "sign"), "Doppler ego-compensated": (compensated, "kind"),
          "points mirrored in z": (mirrored, "height")}


def flags(report: dict) -> dict[str, bool]:
    """Which checks raised a flag: sign not confirmed, kind not radial, road above the
    sensor, any GT finding."""
    kind = report["kind"]
    height = dict(report["rows"]).get("height check", "")
    return {"sign": "FLIPPED" in report["sign"].verdict,
            "kind": kind is not None and (kind.measured == "ego-compensated" or kind.disagrees),
            "height": "above" in height.split(":")[1] if ":" in height else False,
            "gt": bool(report["gt_findings"])}


def study() -> list[dict]:
    base = StoreSequence(SAMPLE)
    rows = []
    try:
        n = len(base)
        pieces = [("whole", 0, n), ("first half", 0, n // 2), ("second half", n // 2, n - n // 2)]
        pieces += [(f"frames {a}-{a + 100}", a, 100) for a in range(0, n - 99, 50)]
        for label, start, frames in pieces:
            piece = FrameRange(base, start, frames)
            rows.append({"input": "correct", "piece": label, **flags(inspect_sequence(piece))})
            for name, (change, _) in FAULTS.items():
                rows.append({"input": name, "piece": label,
                             **flags(inspect_sequence(Altered(piece, change)))})
    finally:
        base.close()
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| input | pieces | sign flagged | kind flagged | height flagged | GT findings |",
             "|---|---:|---:|---:|---:|---:|"]
    for name in ("correct", *FAULTS):
        rs = [r for r in rows if r["input"] == name]
        lines.append(f"| {name} | {len(rs)} | " + " | ".join(
            str(sum(r[k] for r in rs)) for k in ("sign", "kind", "height", "gt")) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description="false alarms and detections of bench inspect's "
                            "sign, kind, height and GT checks on the sample").parse_args(argv)
    rows = study()
    print(table(rows))
    correct = [r for r in rows if r["input"] == "correct"]
    return 1 if any(r["sign"] or r["kind"] or r["height"] for r in correct) else 0


if __name__ == "__main__":
    raise SystemExit(main())
