"""Runs of ``python -m graindyn`` as real subprocesses, and stopping one by SIGTERM once
its log shows it has reached a given point: the interrupted-run tests of every
protocol and engine share these."""
import signal
import subprocess
import sys
import time


def cli(*args, **kw):
    """``python -m graindyn ARGS`` as a real subprocess (stdout and stderr merged)."""
    return subprocess.Popen([sys.executable, "-m", "graindyn", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)


def stop_when_logged(proc, log, text, delay=0.0, timeout=600.0):
    """Send the run ``proc`` SIGTERM once its log file ``log`` holds ``text`` (and
    ``delay`` [s] more have passed), wait for it and check that it stopped on the
    signal; returns its output."""
    deadline = time.time() + timeout
    while time.time() < deadline and not (log.exists() and text in log.read_text()):
        time.sleep(0.02)
    time.sleep(delay)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=timeout)
    assert proc.returncode == 128 + signal.SIGTERM, out
    return out
