"""The event calendar: an indexed binary min-heap of the grains keyed by the time of
each grain's next event, so the next event of the whole system is at the root and a
grain whose event changes moves up or down in O(log N).

One event per grain (the scheme of Smallenburg's "Single" variant, after Lubachevsky
and Rapaport): a grain keeps only the earliest of its predicted events, and an event
whose partner has collided since it was predicted is stale; it is recognised when it
comes up by the partner's collision counter, and the grain is then predicted afresh
(events.py).

Arrays: heap (N,) grain ids in heap order with key (N,) [s] their event times beside
them (the sifts then read contiguous memory, not the grains' scattered times), where
(N,) each grain's place in the heap.  Ties are broken by the grain index, so the order
of events is the same on every machine.
"""
from ..._jit import block_body


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
def sift_down(heap, key, where, k):
    """Move the entry at heap place k down to where its key belongs."""
    n = heap.size
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
def reschedule(heap, key, where, grain, time):
    """Give ``grain`` the key ``time`` [s] and restore the heap order."""
    k = where[grain]
    key[k] = time
    if k > 0 and _earlier(time, grain, key[(k - 1) >> 1], heap[(k - 1) >> 1]):
        sift_up(heap, key, where, k)
    else:
        sift_down(heap, key, where, k)


@block_body
def build_heap(heap, key, where, time):
    """Order all grains by ``time`` (Floyd's bottom-up construction, O(N))."""
    n = heap.size
    for i in range(n):
        heap[i] = i
        key[i] = time[i]
        where[i] = i
    for k in range(n // 2 - 1, -1, -1):
        sift_down(heap, key, where, k)
