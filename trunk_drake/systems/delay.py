"""TransportDelay: y(t) = u(t - delay) for a vector signal, from a history of past steps."""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem
from trunk_drake.systems.weak import weak


@dataclass
class History:
    """Times (s) and values of the input at the starts of the integrator's steps."""

    times: list = field(default_factory=list)
    values: list = field(default_factory=list)


class TransportDelay(LeafSystem):
    """Pure time delay of a vector signal, for continuous-time simulation.

    The input is recorded at the start of every integrator step (a per-step unrestricted
    update of the system's abstract state, so the history lives in the Context) and the
    output interpolates that history linearly at ``t - delay`` (method of steps). Before
    ``t = delay`` the output holds the first recorded value. Steps longer than the delay hold
    the newest value; keep the integrator's maximum step below the delay.
    """

    def __init__(self, size: int, delay: float):
        super().__init__()
        if not (np.isfinite(delay) and delay > 0):
            raise ValueError(f"transport delay must be a positive number of seconds, got {delay!r}")
        self.delay = float(delay)
        self._u = self.DeclareVectorInputPort("u", size)
        self._history = self.DeclareAbstractState(AbstractValue.Make(History()))
        self.DeclareVectorOutputPort("y", size, weak(self._calc),
                                     prerequisites_of_calc={self.time_ticket(), self.abstract_state_ticket(self._history)})
        self.DeclareInitializationUnrestrictedUpdateEvent(weak(self._reset))
        self.DeclarePerStepUnrestrictedUpdateEvent(weak(self._record))

    def _reset(self, context, state):
        state.get_mutable_abstract_state(self._history).set_value(History())
        return self._record(context, state)

    def _record(self, context, state):
        old = state.get_abstract_state(self._history).get_value()
        times, values = list(old.times), list(old.values)
        t = context.get_time()
        if times and t <= times[-1]:
            times.pop()
            values.pop()
        times.append(t)
        values.append(self._u.Eval(context).copy())
        horizon = t - 2 * self.delay
        while len(times) > 2 and times[1] < horizon:
            times.pop(0)
            values.pop(0)
        state.get_mutable_abstract_state(self._history).set_value(History(times, values))
        return EventStatus.Succeeded()

    def _calc(self, context, output):
        history = context.get_abstract_state(self._history).get_value()
        times, values = history.times, history.values
        if not times:  # before initialization: output the current input
            output.SetFromVector(self._u.Eval(context))
            return
        t = context.get_time() - self.delay
        if t <= times[0]:
            output.SetFromVector(values[0])
        elif t >= times[-1]:
            output.SetFromVector(values[-1])
        else:
            k = bisect.bisect_right(times, t)
            w = (t - times[k - 1]) / (times[k] - times[k - 1])
            output.SetFromVector((1 - w) * values[k - 1] + w * values[k])
