"""The rotation between the sensor frame and the ground truth's frame (``bench calibrate``,
``bench inspect``'s check): ``estimate`` (the Doppler and road-plane fit), ``hand_eye`` (the
Doppler-free estimate), ``bootstrap`` (their block-bootstrap intervals), ``pieces`` (does one
rotation fit the whole range), ``write`` (the corrected store) and ``calibrate`` (the command).

May import ``loaders``, ``methods``, ``metrics``, the rest of ``bench.data`` and bench's ground
floor; never ``bench.runs`` or above.
"""
