"""GPU backend on numba-cuda.  Nothing here is imported by ``import graindyn``:
``Simulation(..., backend="gpu")`` imports ``graindyn.engines.soft.gpu.engine`` on its first chunk.
It needs the ``gpu`` extra (numba-cuda) and an NVIDIA GPU, or the CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``, slow: for tests)."""
import importlib.util


def unavailable():
    """Why the GPU backend cannot run here (a sentence), or None when it can."""
    if importlib.util.find_spec("numba_cuda") is None:
        return ("numba-cuda is not installed: pip install 'graindyn[gpu]' (needs an NVIDIA "
                "GPU and driver)")
    from numba import cuda
    try:
        if cuda.is_available():
            return None
    except Exception as err:  # a broken driver or toolkit: report it, do not crash
        return f"numba-cuda cannot reach a GPU ({type(err).__name__}: {err})"
    return "numba-cuda finds no usable NVIDIA GPU on this machine"
