#!/usr/bin/env bash
# The one command of a GPU lease (the device tool's `run`, from the repository root):
#
#     bash benchmarks/gpu_session.sh            carry: [".whl", ".devstate"], timeout_s 560
#
# Before it, here (no GPU needed): the settled states into .devstate and the wheels the
# machine's image lacks into .whl, both folders ignored by git (.git/info/exclude):
#
#     python3 -c "import sys; sys.path.insert(0, '../shared/bench'); import run_all; \
#         [run_all.prepare(c, n, '/tmp/dem_perf_anchors') for c, n in \
#          (('oedo', 280), ('settle', 10000))]"          # LAMMPS settles them, once
#     mkdir -p .devstate && cp /tmp/dem_perf_anchors/state_{oedo_280,settle_10000}.txt .devstate/
#     python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 \
#         --implementation cp --platform manylinux2014_x86_64 -d .whl pydantic==... (see
#         BENCHMARKS.md, "GPU backend")
#
# The machine's own numpy, numba and numba-cuda are used (its image has them); the
# session's stages, their limits and outputs are benchmarks/gpu_session.py's.
set -u
cd "$(dirname "$0")/.."
if ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || echo "the carried wheels did not install"
    export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
python3 benchmarks/gpu_session.py "${OUT:-gpu_session}" "$@"
