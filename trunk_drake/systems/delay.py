"""TransportDelay: y(t) = u(t - delay) for a vector signal, from a history of past steps."""

from __future__ import annotations

import bisect

import numpy as np
from pydrake.systems.framework import LeafSystem


class TransportDelay(LeafSystem):
    """Pure time delay of a vector signal, for continuous-time simulation.

    The input is recorded after every accepted integrator step (a per-step publish event)
    and the output interpolates that history linearly at ``t - delay`` (method of steps).
    Before ``t = delay`` the output holds the first recorded value. Steps longer than the
    delay hold the newest value; keep the integrator's maximum step below the delay.
    Each diagram (and so each simulation) needs its own instance.
    """

    def __init__(self, size: int, delay: float):
        super().__init__()
        if not (np.isfinite(delay) and delay > 0):
            raise ValueError(f"transport delay must be a positive number of seconds, got {delay!r}")
        self.delay = float(delay)
        self._times: list[float] = []
        self._values: list[np.ndarray] = []
        self.DeclareVectorInputPort("u", size)
        self.DeclareVectorOutputPort("y", size, self._calc, prerequisites_of_calc={self.time_ticket()})
        self.DeclareInitializationPublishEvent(self._reset)
        self.DeclarePerStepPublishEvent(self._record)

    def _reset(self, context):
        self._times, self._values = [], []
        self._record(context)

    def _record(self, context):
        t = context.get_time()
        if self._times and t <= self._times[-1]:
            self._times.pop()
            self._values.pop()
        self._times.append(t)
        self._values.append(self.get_input_port(0).Eval(context).copy())
        horizon = t - 2 * self.delay
        while len(self._times) > 2 and self._times[1] < horizon:
            self._times.pop(0)
            self._values.pop(0)

    def _calc(self, context, output):
        if not self._times:  # before initialization: output the current input
            output.SetFromVector(self.get_input_port(0).Eval(context))
            return
        t = context.get_time() - self.delay
        times = self._times
        if t <= times[0]:
            output.SetFromVector(self._values[0])
        elif t >= times[-1]:
            output.SetFromVector(self._values[-1])
        else:
            k = bisect.bisect_right(times, t)
            w = (t - times[k - 1]) / (times[k] - times[k - 1])
            output.SetFromVector((1 - w) * self._values[k - 1] + w * self._values[k])
