#!/usr/bin/env bash
# A GPU lease in one command, from the repository root:
#
#     bash benchmarks/gpu_session.sh prepare    here, first (no GPU; LAMMPS and pip)
#     bash benchmarks/gpu_session.sh            on the machine: the device tool's run,
#                                               carry [".whl", ".devstate"], timeout_s 560
#
# prepare: the settled states of ../shared/bench (LAMMPS settles them, some minutes;
# the GPU machine has no LAMMPS) into .devstate, and the wheels the machine's image
# lacks (for its Python 3.12, the versions installed here) into .whl; both folders are
# put in .git/info/exclude.  On the machine its own numpy, numba and numba-cuda are
# used; the stages, their limits and outputs are benchmarks/gpu_session.py's.
set -u
cd "$(dirname "$0")/.."
WHEELS="pydantic pydantic_core annotated-types typing-inspection typing_extensions tomli_w
meshio dask distributed partd locket tblib tornado zict"
if [ "${1:-}" = prepare ]; then
    set -e
    mkdir -p .git/info .devstate .whl
    for path in /.whl/ /.devstate/; do
        grep -qxF "$path" .git/info/exclude 2>/dev/null || echo "$path" >> .git/info/exclude
    done
    work=${TMPDIR:-/tmp}/dem_perf_anchors
    mkdir -p "$work"
    python3 -c "import sys; sys.path.insert(0, '../shared/bench'); import run_all
for case, n in (('oedo', 280), ('settle', 10000)): run_all.prepare(case, n, '$work')"
    cp "$work"/state_oedo_280.txt "$work"/state_settle_10000.txt .devstate/
    pins=$(for name in $WHEELS; do
        python3 -m pip show "$name" 2>/dev/null | awk -v n="$name" '/^Version:/ {print n "==" $2}'
    done)
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
        --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux2014_x86_64 \
        --platform manylinux1_x86_64 -d .whl $pins
    du -sh .devstate .whl
    exit 0
fi
if ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || echo "the carried wheels did not install"
    export PYTHONPATH=/tmp/site${PYTHONPATH:+:$PYTHONPATH}
fi
python3 benchmarks/gpu_session.py "${OUT:-gpu_session}" "$@"
