"""The data room: datasets into stores and back out - ``bench convert``, ``inspect``, ``synth``,
``export``, ``calibrate`` and the dataset catalogue.

May import ``loaders``, ``methods``, ``metrics`` and bench's ground floor (``bench.guard``,
``paths``, ``threads``, ``console``); never ``bench.runs`` or anything above it.
The rotation between sensor and ground truth lives in ``calibration/``.
"""
