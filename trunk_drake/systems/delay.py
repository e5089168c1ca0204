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
    the newest value; keep the integrator's maximum step below the delay. `delay` is one value,
    or one per element (copies of a model with delays of their own).
    """

    def __init__(self, size: int, delay):
        super().__init__()
        delays = np.broadcast_to(np.asarray(delay, float), (size,))
        if not (np.all(np.isfinite(delays)) and np.all(delays > 0)):
            raise ValueError(f"transport delay must be a positive number of seconds, got {delay!r}")
        self.delay = float(delays.max())  # the longest: how far back the history reaches
        # elements by delay: (delay, their indices); one entry when all share it
        self._blocks = [(float(d), np.flatnonzero(delays == d)) for d in np.unique(delays)]
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
        if len(self._blocks) == 1:
            output.SetFromVector(_at(times, values, context.get_time() - self.delay))
            return
        y = np.empty(len(values[0]))
        for delay, elements in self._blocks:
            y[elements] = _at(times, values, context.get_time() - delay, elements)
        output.SetFromVector(y)


def _at(times: list, values: list, t: float, elements=slice(None)) -> np.ndarray:
    """The recorded input (its `elements`) at time t: linear between the recorded steps, held beyond them."""
    if t <= times[0]:
        return values[0][elements]
    if t >= times[-1]:
        return values[-1][elements]
    k = bisect.bisect_right(times, t)
    w = (t - times[k - 1]) / (times[k] - times[k - 1])
    return (1 - w) * values[k - 1][elements] + w * values[k][elements]
