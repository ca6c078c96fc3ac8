"""Command line shared by the example scripts: --grains, --seed and --out."""
import argparse
import pathlib

import numpy as np


def parse(doc, name):
    """(args, output folder (created), random generator) for the example whose module
    docstring is ``doc``; its output goes to runs/<name> unless --out says otherwise."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--grains", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default=f"runs/{name}")
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return args, out, np.random.default_rng(args.seed)
