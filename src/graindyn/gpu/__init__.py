"""GPU backend on numba-cuda (issue 6).  Nothing here is imported by ``import graindyn``:
``graindyn.gpu.engine.DeviceSimulation`` needs the ``gpu`` extra (numba-cuda) and a GPU,
or the CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) for tests."""
