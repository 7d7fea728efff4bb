"""Test-only methods, loaded by workers through DOPPLER_BENCH_METHODS (never registered in the
package): one that aborts the process like a crashing native library, one that sleeps."""

from __future__ import annotations

import os
import time

import numpy as np
from pydantic import Field

from methods.base import MethodParams, Registration, RegistrationResult


class AbortingMethod(Registration):
    name = "test-abort"
    description = "test only: aborts the process (SIGABRT) on the first registration"
    uses_initial_guess = False

    def register(self, source, target, init_T_target_source):
        os.abort()


class SleepParams(MethodParams):
    sleep_s: float = Field(0.05, ge=0, description="sleep per frame in the timed call [s]")
    untimed_sleep_s: float = Field(0.0, ge=0, description="sleep per frame in preprocess, "
                                   "outside the timed section and its lock [s]")


class SleepingMethod(Registration):
    name = "test-sleep"
    description = "test only: returns the identity after sleeping"
    uses_initial_guess = False
    Params = SleepParams

    def preprocess(self, scan):
        time.sleep(self.params.untimed_sleep_s)
        return scan

    def register(self, source, target, init_T_target_source):
        time.sleep(self.params.sleep_s)
        return RegistrationResult(np.eye(4), len(source), 1, True)


METHODS = [AbortingMethod, SleepingMethod]
