"""Which compiled law loops run in SIMD lanes: LLVM's own verdict, law by law.

    python benchmarks/law_loops.py [--all]

The CPU's law loop (engines/soft/law_loop.py) has two loops: the geometry of a batch
of pairs, then the law over it.  Each is fast only when LLVM's loop vectorizer takes it:
a law with a branch that cannot become a select, an inner loop, or a call LLVM does not
know (numba's min, max and ``x ** 2`` among them) keeps the whole law loop scalar, two
to three times slower per contact (BENCHMARKS.md, the oedometer), with the same
numbers, so that no test sees it.  This compiles the law loop afresh (no disk cache)
for each model composition: every law of each mode in place of the one of a base
composition (hertz, tsuji, mindlin, no rolling, no twisting), the compositions of
examples/*.toml, and with ``--all`` every composition ContactModel accepts; it prints
for each how many of the two loops were vectorized, at what width, and LLVM's reasons
for those that were not (its loop-vectorize remarks, read from its standard error).
"""
import glob
import itertools
import os
import pathlib
import re
import sys
import tempfile
import tomllib

import llvmlite.binding as llvm

# before anything compiles: LLVM reports on every loop it vectorizes or leaves
for option in ("-pass-remarks=loop-vectorize", "-pass-remarks-missed=loop-vectorize",
               "-pass-remarks-analysis=loop-vectorize"):
    llvm.set_option("", option)

import numba  # noqa: E402

from graindyn.core.species import ContactModel  # noqa: E402
from graindyn.engines.soft import law_loop  # noqa: E402
from graindyn.physics import registry  # noqa: E402

MODES = ("normal", "damping", "tangential", "rolling", "twisting")
BASE = ("hertz", "tsuji", "mindlin", "none", "none")


def compositions(everything):
    """(source, composition) pairs to compile, each composition once."""
    out = {}
    for k, mode in enumerate(MODES):
        for name in getattr(registry, mode.upper()):
            out.setdefault(BASE[:k] + (name,) + BASE[k + 1:], f"{mode} law")
    root = pathlib.Path(__file__).resolve().parent.parent
    for path in sorted(glob.glob(str(root / "examples" / "*.toml"))):
        contact = tomllib.loads(pathlib.Path(path).read_text()).get("contact")
        if contact:
            key = tuple(contact.get(mode, "none") for mode in MODES)
            out[key] = f"{out.get(key, '')} {pathlib.Path(path).name}".strip()
    if everything:
        for key in itertools.product(*(getattr(registry, m.upper()) for m in MODES)):
            out.setdefault(key, "")
    return out


def verdict(composition):
    """LLVM's loop-vectorize remarks on the law loop of ``composition``."""
    ids = ContactModel(**dict(zip(MODES, composition))).ids()
    law_loop._LOOPS.clear()
    with tempfile.TemporaryFile(mode="w+") as caught:
        saved = os.dup(2)
        sys.stderr.flush()
        os.dup2(caught.fileno(), 2)
        try:
            law_loop.law_address(ids)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        caught.seek(0)
        remarks = [line.split("remark: ")[-1].split(": ", 1)[-1].strip()
                   for line in caught.read().splitlines() if "remark:" in line]
    widths = [int(w) for r in remarks for w in re.findall(r"vectorization width: (\d+)", r)]
    missed = sorted({r for r in remarks if r.startswith("loop not vectorized")})
    return widths, missed


def main(argv):
    # a fresh compilation, so that LLVM runs (and speaks) for every composition
    law_loop.callback = lambda signature: numba.cfunc(signature, error_model="numpy")
    print(f"{'normal, damping, tangential, rolling, twisting':52s} vectorized  width  "
          f"(from)  LLVM's reasons for the others")
    for composition, source in compositions("--all" in argv).items():
        try:
            widths, missed = verdict(composition)
        except ValueError as refused:          # a composition ContactModel refuses
            print(f"{', '.join(composition):52s} refused: {refused}")
            continue
        print(f"{', '.join(composition):52s} {len(widths)} of 2      "
              f"{','.join(map(str, widths)) or '-':5s}  ({source})  {'; '.join(missed)}")


if __name__ == "__main__":
    main(sys.argv[1:])
