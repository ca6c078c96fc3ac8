"""HDF5 checkpoints: every array of ``Simulation.snapshot`` plus the run's JSON state
(config, protocol phase, outputs written, random generator), written atomically.

Layout: one dataset per snapshot array, named by its path ("grains/positions",
"pairs/history", ...); attributes ``format`` (CHECKPOINT_FORMAT), ``version`` (graindyn),
``step``, ``time`` and ``meta`` (a JSON string).  A checkpoint is written to
``<name>.tmp``, flushed and fsynced, then the last good checkpoint becomes
``checkpoint.prev.h5`` and the new one is renamed into place: a crash at any moment
leaves at least one complete checkpoint.
"""
import json
import os
import pathlib

import h5py
import numpy as np

from .. import __version__

CHECKPOINT_FORMAT = 2  # 2: walls/motion_kind and walls/motion (servo state) added
LATEST = "checkpoint.h5"
PREVIOUS = "checkpoint.prev.h5"


class CheckpointError(RuntimeError):
    """A checkpoint that cannot be used: missing, corrupted or from another format."""


def write(folder, arrays, meta, step, time):
    """Write ``arrays`` (name -> ndarray) and ``meta`` (JSON-able) as the latest checkpoint
    in ``folder``; returns its path."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / (LATEST + ".tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs["format"] = CHECKPOINT_FORMAT
        f.attrs["version"] = __version__
        f.attrs["step"] = int(step)
        f.attrs["time"] = float(time)
        f.attrs["meta"] = json.dumps(meta)
        for name, value in arrays.items():
            f.create_dataset(name, data=value)
        f.flush()
        os.fsync(f.id.get_vfd_handle())
    latest = folder / LATEST
    if latest.exists():
        os.replace(latest, folder / PREVIOUS)
    os.replace(tmp, latest)
    return latest


def read(path):
    """(arrays, meta, step, time) of one checkpoint file; CheckpointError if unusable."""
    path = pathlib.Path(path)
    try:
        with h5py.File(path, "r") as f:
            fmt = int(f.attrs.get("format", -1))
            if fmt != CHECKPOINT_FORMAT:
                raise CheckpointError(
                    f"{path}: checkpoint format {fmt} written by graindyn "
                    f"{f.attrs.get('version', '?')}; this graindyn {__version__} reads format "
                    f"{CHECKPOINT_FORMAT} only")
            arrays = {}
            f.visititems(lambda name, obj: arrays.__setitem__(name, np.array(obj))
                         if isinstance(obj, h5py.Dataset) else None)
            return arrays, json.loads(f.attrs["meta"]), int(f.attrs["step"]), \
                float(f.attrs["time"])
    except CheckpointError:
        raise
    except (OSError, KeyError, ValueError) as err:
        raise CheckpointError(f"{path}: not a readable checkpoint ({err})") from None


def latest(folder, warn=print):
    """The newest readable checkpoint in ``folder``: the latest, or the previous one (with
    a warning) when the latest is corrupted or truncated."""
    folder = pathlib.Path(folder)
    candidates = [folder / LATEST, folder / PREVIOUS]
    errors = []
    for path in candidates:
        if not path.exists():
            continue
        try:
            found = read(path)
        except CheckpointError as err:
            errors.append(str(err))
            continue
        if errors:
            warn(f"warning: {errors[0]}; resuming from the previous checkpoint {path.name}")
        return found
    if errors:
        raise CheckpointError("no usable checkpoint: " + "; ".join(errors))
    raise CheckpointError(f"no checkpoint in {folder}")
