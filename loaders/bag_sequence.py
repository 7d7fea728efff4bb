"""What the ROS1-bag radar loaders share: the topic index, the frame stamps (sorted, repeats
dropped) and the association of ground truth with them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loaders.assemble import median_period
from loaders.errors import DataError
from loaders.gt import associate
from loaders.ros1 import BagTopic, sort_unique_stamps, topic_stamps
from loaders.scan import SensorInfo, Sequence
from loaders.trajectory import Trajectory


class BagRadarSequence(Sequence):
    """Radar scans from one topic of one or more bags, read lazily. Subclasses call
    ``_open_topic``, then ``_frame_stamps``, then ``_finish``, and implement ``scan``."""

    def _open_topic(self, bags, topic: str, accept=None) -> None:
        if isinstance(bags, str | Path):
            bags = [bags]
        self.bags = [Path(b) for b in bags]
        self.topic = topic
        self._index = (BagTopic(self.bags, topic, accept=accept) if accept is not None
                       else BagTopic(self.bags, topic))

    @property
    def where(self) -> str:
        return ", ".join(str(b) for b in self.bags)

    def _frame_stamps(self, stamp: str) -> tuple[np.ndarray, np.ndarray, int]:
        """(stamps of every message, order of the unique sorted ones, repeats dropped)."""
        if len(self._index) == 0:
            raise DataError(f"{self.bags[0]}: topic {self.topic} has no messages")
        stamps = topic_stamps(self._index, stamp, self.where)
        self._stamp_mode = stamp
        order, dropped = sort_unique_stamps(stamps, self.where)
        return stamps, order, dropped

    def _finish(self, stamps: np.ndarray, order: np.ndarray, gt: Trajectory | None,
                gt_label: str | None, T_body_sensor: np.ndarray, default_period_s: float,
                model: str, **association) -> None:
        """Associate ground truth and set the sensor. Every frame is kept (with
        ``uncovered="trim"`` every frame from the first to the last with GT); frames without
        GT are excluded from scoring only."""
        self.ground_truth = None
        if gt is not None:
            assoc = associate(gt, stamps[order], T_body_sensor=T_body_sensor,
                              gt_file=gt_label, scan_file=self.where, **association)
            order = order[assoc.keep]
            self.ground_truth = assoc.ground_truth
            self.provenance["gt_association"] = assoc.report
        self._order = order
        self._stamps = stamps[order]
        self.sensor = SensorInfo("radar", median_period(self._stamps, default_period_s),
                                 T_body_sensor, model)

    def __len__(self) -> int:
        return len(self._order)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def close(self) -> None:
        self._index.close()
