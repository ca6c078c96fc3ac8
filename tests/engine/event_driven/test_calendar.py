"""The event calendar (engines/event_driven/calendar.py): the front is always the
earliest event of all grains, ties broken by the grain index, through every path an
event can take (the heap, a bucket's list, the overflow, a jump over empty buckets,
events at no finite time)."""
import math

import numpy as np
import pytest

from graindyn.engines.event_driven.calendar import build, calendar_for, front, reschedule


def earliest(times):
    """(grain, time) of the earliest event, ties to the lowest grain."""
    i = int(np.lexsort((np.arange(times.size), times))[0])
    return i, times[i]


@pytest.mark.parametrize("n, seed", [(1, 0), (7, 1), (300, 2), (5000, 3)])
def test_the_front_is_the_earliest_event_through_any_sequence(n, seed):
    """Events are taken in time order and rescheduled as the event loop does (the
    grain at the front to a later time, some others too), with exponential times
    ahead, a few far ones (beyond every bucket), some at the same instant and some
    at no finite time: the front matches a sorted reference at every step."""
    rng = np.random.default_rng(seed)
    cal = calendar_for(n)
    now = 0.0
    cal.time[:] = rng.exponential(1.0, n)
    cal.time[rng.random(n) < 0.05] = math.inf
    build(cal, now)
    for step in range(min(20 * n + 50, 6100)):    # the smaller ones wrap their lists
        i = front(cal)
        t = cal.key[0]
        assert (i, t) == earliest(cal.time), step
        if t == math.inf:
            break
        now = t
        for grain in [i] + list(rng.integers(0, n, 2)):
            u = rng.random()
            new = now if u < 0.05 else math.inf if u < 0.08 \
                else now + 1e3 * rng.exponential(1.0) if u < 0.12 \
                else now + rng.exponential(1.0)
            cal.time[grain] = new
            reschedule(cal, grain, new)


def test_every_event_at_no_finite_time_leaves_an_infinite_front():
    cal = calendar_for(10)
    cal.time[:] = math.inf
    build(cal, 0.0)
    assert front(cal) == 0 and cal.key[0] == math.inf
    cal.time[3] = 2.5
    reschedule(cal, 3, 2.5)
    assert front(cal) == 3 and cal.key[0] == 2.5
