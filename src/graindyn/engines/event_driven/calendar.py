"""The event calendar: every grain's next event, in a queue of buckets on the time axis
whose front bucket is an indexed binary min-heap (after Paul, J. Comput. Phys. 221, 615
(2007), the queue of the published event-driven codes), so that the next event of the
whole system and a grain whose event changes cost O(1) on average, not O(log N).

One event per grain (the scheme of Smallenburg's "Single" variant, after Lubachevsky
and Rapaport): a grain keeps only the earliest of its predicted events, and an event
whose partner has collided since it was predicted is stale; it is recognised when it
comes up by the partner's collision counter, and the grain is then predicted afresh
(events.py).

The time after ``origin`` [s] is cut into buckets of ``width`` [s]; bucket b holds the
events in [origin + b width, origin + (b + 1) width).  The events of the current bucket
c and of any earlier time are in the heap; those of buckets c + 1 ... c + B - 1 in B
doubly linked lists (slot b mod B, B a power of two), and those further on in one
overflow list, which is sorted into the buckets each time c passes a multiple of B
(every event there is then less than B buckets ahead: it gets its bucket before c
reaches it).  Taking the front moves c on through the empty buckets, each bucket's
list into the heap when c reaches it.  Bucket numbers grow with time, so the events
leave the calendar in the order of their times, ties broken by the grain index: the
order of a single heap, the same on every machine.  ``width`` is set when the calendar
is built (``build``) so that a bucket holds a few events (``PER_BUCKET``).

Arrays (bundles.Calendar): heap (N,) grain ids in heap order with key (N,) [s] their
event times beside them (the sifts read contiguous memory), where (N,) each grain's
place in the heap; bucket (N,) the grain's bucket (IN_HEAP, OVERFLOW or its number),
after, before (N,) its neighbours in its list (-1: none), first (B + 1,) the first
grain of each list (slot B the overflow's); span (2,) [s] origin and width; cursor
(2,) the current bucket c and the heap's size.
"""
import math

import numpy as np

from ..._jit import block_body

IN_HEAP, OVERFLOW = -1, -2
CURRENT, SIZE = 0, 1            # cursor slots
ORIGIN, WIDTH = 0, 1            # span slots
PER_BUCKET = 8.0                # events a bucket is sized to hold near the front


def calendar_for(n):
    """An empty bundles.Calendar for n grains, with B bucket lists, the power of two
    at or above n / 2 (at least 2)."""
    from .bundles import Calendar

    lists = 1 << max(1, math.ceil(math.log2(max(n, 2) / 2)))
    times = {name: np.zeros(n) for name in ("time", "next_time", "cross_time", "key")}
    ids = {name: np.zeros(n, np.int64)
           for name in ("kind", "partner", "count", "face", "heap", "where")}
    return Calendar(**times, **ids, bucket=np.full(n, OVERFLOW, np.int64),
                    after=np.full(n, -1, np.int64), before=np.full(n, -1, np.int64),
                    first=np.full(lists + 1, -1, np.int64), span=np.array([0.0, 1.0]),
                    cursor=np.zeros(2, np.int64))


@block_body
def _earlier(ta, a, tb, b):
    return ta < tb or (ta == tb and a < b)


@block_body
def sift_up(heap, key, where, k):
    """Move the entry at heap place k up to where its key belongs."""
    grain = heap[k]
    t = key[k]
    while k > 0:
        parent = (k - 1) >> 1
        if not _earlier(t, grain, key[parent], heap[parent]):
            break
        heap[k] = heap[parent]
        key[k] = key[parent]
        where[heap[k]] = k
        k = parent
    heap[k] = grain
    key[k] = t
    where[grain] = k


@block_body
def sift_down(heap, key, where, k, n):
    """Move the entry at heap place k of a heap of n entries down to where its key
    belongs."""
    grain = heap[k]
    t = key[k]
    while True:
        child = 2 * k + 1
        if child >= n:
            break
        if child + 1 < n and _earlier(key[child + 1], heap[child + 1], key[child],
                                      heap[child]):
            child += 1
        if not _earlier(key[child], heap[child], t, grain):
            break
        heap[k] = heap[child]
        key[k] = key[child]
        where[heap[k]] = k
        k = child
    heap[k] = grain
    key[k] = t
    where[grain] = k


@block_body
def _push(cal, grain, time):
    n = cal.cursor[SIZE]
    cal.heap[n] = grain
    cal.key[n] = time
    cal.bucket[grain] = IN_HEAP
    cal.cursor[SIZE] = n + 1
    sift_up(cal.heap, cal.key, cal.where, n)


@block_body
def _drop_from_heap(cal, grain):
    n = cal.cursor[SIZE] - 1
    cal.cursor[SIZE] = n
    k = cal.where[grain]
    if k == n:
        return
    cal.heap[k] = cal.heap[n]
    cal.key[k] = cal.key[n]
    cal.where[cal.heap[k]] = k
    if k > 0 and _earlier(cal.key[k], cal.heap[k], cal.key[(k - 1) >> 1],
                          cal.heap[(k - 1) >> 1]):
        sift_up(cal.heap, cal.key, cal.where, k)
    else:
        sift_down(cal.heap, cal.key, cal.where, k, n)


@block_body
def _link(cal, grain, slot, bucket):
    head = cal.first[slot]
    cal.bucket[grain] = bucket
    cal.before[grain] = -1
    cal.after[grain] = head
    if head >= 0:
        cal.before[head] = grain
    cal.first[slot] = grain


@block_body
def _unlink(cal, grain, slot):
    a = cal.after[grain]
    b = cal.before[grain]
    if b >= 0:
        cal.after[b] = a
    else:
        cal.first[slot] = a
    if a >= 0:
        cal.before[a] = b


@block_body
def _slot(cal, bucket):
    """The list of ``bucket`` (a number or OVERFLOW)."""
    lists = cal.first.size - 1
    return lists if bucket == OVERFLOW else bucket & (lists - 1)


@block_body
def _insert(cal, grain, time):
    """Put ``grain`` with event ``time`` [s] where it belongs: the heap, a bucket's list
    or the overflow."""
    x = (time - cal.span[ORIGIN]) / cal.span[WIDTH]
    c = cal.cursor[CURRENT]
    if x < c + 1:
        _push(cal, grain, time)
    elif x < c + cal.first.size - 1:
        b = np.int64(x)
        _link(cal, grain, _slot(cal, b), b)
    else:
        _link(cal, grain, cal.first.size - 1, OVERFLOW)


@block_body
def reschedule(cal, grain, time):
    """Give ``grain`` the event time ``time`` [s] (cal.time[grain] holds it too)."""
    b = cal.bucket[grain]
    if b == IN_HEAP:
        if (time - cal.span[ORIGIN]) / cal.span[WIDTH] < cal.cursor[CURRENT] + 1:
            k = cal.where[grain]
            cal.key[k] = time
            if k > 0 and _earlier(time, grain, cal.key[(k - 1) >> 1],
                                  cal.heap[(k - 1) >> 1]):
                sift_up(cal.heap, cal.key, cal.where, k)
            else:
                sift_down(cal.heap, cal.key, cal.where, k, cal.cursor[SIZE])
            return
        _drop_from_heap(cal, grain)
    else:
        _unlink(cal, grain, _slot(cal, b))
    _insert(cal, grain, time)


@block_body
def _sort_overflow(cal):
    """Move the overflow's events that are now less than B buckets ahead into their
    buckets (or the heap)."""
    lists = cal.first.size - 1
    grain = cal.first[lists]
    while grain >= 0:
        after = cal.after[grain]
        t = cal.time[grain]
        if (t - cal.span[ORIGIN]) / cal.span[WIDTH] < cal.cursor[CURRENT] + lists:
            _unlink(cal, grain, lists)
            _insert(cal, grain, t)
        grain = after


@block_body
def _advance(cal):
    """Move on to the next bucket: its list into the heap (every event of a list slot
    has the one bucket number of that slot that lies within B of the current)."""
    c = cal.cursor[CURRENT] + 1
    cal.cursor[CURRENT] = c
    lists = cal.first.size - 1
    if c & (lists - 1) == 0:
        _sort_overflow(cal)
    _pour(cal, c & (lists - 1))


@block_body
def _pour(cal, slot):
    """Every event of list ``slot`` into the heap."""
    grain = cal.first[slot]
    cal.first[slot] = -1
    while grain >= 0:
        after = cal.after[grain]
        _push(cal, grain, cal.time[grain])
        grain = after


@block_body
def _leap(cal):
    """Every list empty, the heap too: jump the current bucket to the overflow's
    earliest event (all of them into the heap if none is finite)."""
    lists = cal.first.size - 1
    earliest = math.inf
    grain = cal.first[lists]
    while grain >= 0:
        earliest = min(earliest, cal.time[grain])
        grain = cal.after[grain]
    if earliest < math.inf:
        cal.cursor[CURRENT] = np.int64((earliest - cal.span[ORIGIN]) / cal.span[WIDTH]) - 1
        _sort_overflow(cal)
        return
    _pour(cal, lists)


@block_body
def front(cal):
    """The grain whose event is the next of the system (the heap's root after moving on
    through the empty buckets); its time is cal.key[0]."""
    lists = cal.first.size - 1
    empty = 0
    while cal.cursor[SIZE] == 0:
        if empty >= lists:
            _leap(cal)
            empty = 0
            if cal.cursor[SIZE] > 0:
                break
        _advance(cal)
        empty += 1
    return cal.heap[0]


@block_body
def _select(values, n, k):
    """The k-th smallest of values[:n] (Hoare's selection, in place)."""
    lo, hi = 0, n - 1
    while lo < hi:
        pivot = values[(lo + hi) >> 1]
        i, j = lo, hi
        while i <= j:
            while values[i] < pivot:
                i += 1
            while values[j] > pivot:
                j -= 1
            if i <= j:
                values[i], values[j] = values[j], values[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return values[k]


@block_body
def build(cal, now):
    """Put every grain into the calendar by cal.time, the buckets starting at ``now``
    [s], their width PER_BUCKET times the mean time between the events to come (from
    the median time ahead, as if the times ahead were exponential: N events in a mean
    time ahead of median / ln 2)."""
    n = cal.time.size
    ahead = cal.key                 # free until the grains are put in: the times ahead
    finite = 0
    for i in range(n):
        if cal.time[i] < math.inf:
            ahead[finite] = max(cal.time[i] - now, 0.0)
            finite += 1
    median = _select(ahead, finite, finite // 2) if finite > 0 else 0.0
    width = PER_BUCKET * median / math.log(2.0) / max(finite, 1)
    cal.span[ORIGIN] = now
    cal.span[WIDTH] = width if width > 0.0 else 1.0
    cal.cursor[CURRENT] = 0
    cal.cursor[SIZE] = 0
    cal.first[:] = -1
    for i in range(n):
        _insert(cal, i, cal.time[i])
