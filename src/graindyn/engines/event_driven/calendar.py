"""The event calendar: an indexed binary min-heap of the grains keyed by the time of
each grain's next event, so the next event of the whole system is at the root and a
grain whose event changes moves up or down in O(log N).

One event per grain (the scheme of Smallenburg's "Single" variant, after Lubachevsky
and Rapaport): a grain keeps only the earliest of its predicted events, and an event
whose partner has collided since it was predicted is stale; it is recognised when it
comes up by the partner's collision counter, and the grain is then predicted afresh
(events.py).

Arrays: heap (N,) grain ids in heap order, where (N,) each grain's place in the heap,
time (N,) [s] each grain's event time (the key).  Ties are broken by the grain index, so
the order of events is the same on every machine.
"""
from ..._jit import driver


@driver
def _earlier(time, a, b):
    return time[a] < time[b] or (time[a] == time[b] and a < b)


@driver
def sift_up(heap, where, time, k):
    """Move the entry at heap place k up to where its key belongs."""
    grain = heap[k]
    while k > 0:
        parent = (k - 1) >> 1
        other = heap[parent]
        if not _earlier(time, grain, other):
            break
        heap[k] = other
        where[other] = k
        k = parent
    heap[k] = grain
    where[grain] = k


@driver
def sift_down(heap, where, time, k):
    """Move the entry at heap place k down to where its key belongs."""
    n = heap.size
    grain = heap[k]
    while True:
        child = 2 * k + 1
        if child >= n:
            break
        if child + 1 < n and _earlier(time, heap[child + 1], heap[child]):
            child += 1
        other = heap[child]
        if not _earlier(time, other, grain):
            break
        heap[k] = other
        where[other] = k
        k = child
    heap[k] = grain
    where[grain] = k


@driver
def reschedule(heap, where, time, grain):
    """Restore the heap order after ``time[grain]`` changed."""
    k = where[grain]
    if k > 0 and _earlier(time, grain, heap[(k - 1) >> 1]):
        sift_up(heap, where, time, k)
    else:
        sift_down(heap, where, time, k)


@driver
def build_heap(heap, where, time):
    """Order all grains by ``time`` (Floyd's bottom-up construction, O(N))."""
    n = heap.size
    for i in range(n):
        heap[i] = i
        where[i] = i
    for k in range(n // 2 - 1, -1, -1):
        sift_down(heap, where, time, k)
