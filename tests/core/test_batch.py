"""gpu.batch.Batch without a GPU: the rounds in which the jobs' chunks are gathered
(the device round itself replaced by a recorder), exceptions of a job and of a round.
The device side is checked under the CUDA simulator in tests/gpu."""
import threading

from graindyn.engines.soft import loop
from graindyn.engines.soft.gpu.batch import Batch


class Recorder(Batch):
    """A Batch whose rounds record which simulations asked for how many steps."""

    def __init__(self, fail_round=None):
        super().__init__()
        self.seen = []
        self.fail_round = fail_round

    def _round(self, requests):
        self.rounds += 1
        if self.rounds == self.fail_round:
            raise RuntimeError("device lost")
        self.seen.append({sim: n for sim, (_, n) in requests.items()})
        return {sim: (loop.DONE, n) for sim, (_, n) in requests.items()}


def job(batch, name, chunks):
    def run():
        done = 0
        for n in chunks:
            status, steps = batch.chunk(name, n)
            assert status == loop.DONE and steps == n
            done += steps
        return done
    return run


def test_chunks_of_running_jobs_go_together():
    """Each round holds one chunk of every job still running, whatever the thread
    timing; jobs end independently, and results come back in job order."""
    batch = Recorder()
    ended = []
    results = batch.run([job(batch, "a", [5, 5, 5]), job(batch, "b", [7]),
                         job(batch, "c", [1, 2])],
                        done=lambda k, r: ended.append((k, threading.current_thread())))
    assert results == [15, 7, 3]
    assert batch.seen == [{"a": 5, "b": 7, "c": 1}, {"a": 5, "c": 2}, {"a": 5}]
    assert sorted(k for k, _ in ended) == [0, 1, 2]
    assert all(t is threading.main_thread() for _, t in ended)


def test_a_failing_job_and_a_failing_round_are_reported_to_their_jobs():
    batch = Recorder(fail_round=2)

    def broken():
        batch.chunk("x", 3)
        raise ValueError("bad protocol")

    results = batch.run([broken, job(batch, "y", [4, 4])])
    assert isinstance(results[0], ValueError)
    assert isinstance(results[1], RuntimeError) and "device lost" in str(results[1])


def test_job_threads_take_turns_between_chunks_and_never_overlap_a_round():
    """Between chunks a job may launch kernels of its own (energies, contacts), and the
    CUDA simulator's kernels are not thread-safe: at most one job thread runs at a
    time, and none while a round runs.  Each job spends time between its chunks
    (a sleep lets the other threads run); the spans recorded must not overlap."""
    import time

    spans = []
    inside = []

    class Timed(Recorder):
        def _round(self, requests):
            inside.append("round")
            assert inside == ["round"], inside
            time.sleep(0.002)
            inside.remove("round")
            return super()._round(requests)

    batch = Timed()

    def busy(name):
        def run():
            for n in (1, 2, 3):
                inside.append(name)
                assert inside == [name], inside
                start = time.perf_counter()
                time.sleep(0.002)
                spans.append((start, time.perf_counter()))
                inside.remove(name)
                batch.chunk(name, n)
            return name
        return run

    assert batch.run([busy(k) for k in "abcd"]) == list("abcd")
    assert batch.seen[0] == dict.fromkeys("abcd", 1) and len(batch.seen) == 3
    spans.sort()
    assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:]))
