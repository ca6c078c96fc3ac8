"""The procedure run alone of the 1000-cycle study (the retry settings), from the study's
bed, for the folders whose full DEM path is the one stored in this folder (full DEM is
not run again):

    python procedure_only.py SEED OUT [KEY=VALUE ...]

KEY=VALUE (TOML values) go on the retry settings (``protocol.extrapolation`` chooses
the estimator, linear by default); PERTURB=1e-9 in the environment runs it from the bed
with one grain moved by that much, as a replica.  Writes OUT/bed,
OUT/runs/ESTIMATOR_ki30_k10_h20 and OUT/record.json (the run's record, with its path).
"""
import json
import os
import pathlib
import sys
import tomllib

from graindyn.studies.settlement import prepare_bed, run_from_bed, study_plan

RETRY = {"protocol.relaxation": "excess", "protocol.keep_contacts": True,
         "protocol.restart_cycles": 1, "protocol.smoothing": 3,
         "protocol.extrapolated_growth": 2, "protocol.relaxation_tolerance": 1e-3,
         "protocol.final_cycles": 11, "protocol.jump_tolerance": 0.005,
         "protocol.undone_jump": "retry"}


def main(seed, out, settings):
    overrides = {**RETRY, "run.seed": seed}
    for item in settings:
        key, _, text = item.partition("=")
        overrides[key] = tomllib.loads(f"v = {text}")["v"]
    estimator = overrides.pop("protocol.extrapolation", "linear")
    data, runs, _, _ = study_plan(grains=430, cycles=1000, initial_cycles=30, ks=[10],
                                  hs=[20], k_fixed=10, h_fixed=20, estimator=estimator,
                                  mode="fully", overrides=overrides, replicas=0,
                                  procedure_replicas=0)
    name = f"{estimator}_ki30_k10_h20"
    out.mkdir(parents=True, exist_ok=True)
    prepare_bed(data, out / "bed")
    record = run_from_bed(out / "bed", runs[name], out / "runs" / name, threads=1,
                          perturbation=float(os.environ.get("PERTURB", "0")))
    (out / "record.json").write_text(json.dumps(record, default=str))
    print(f"{name}: settlement {record['settlement_m']} m, {record['cpu_s']:.0f} CPU s")


if __name__ == "__main__":
    main(int(sys.argv[1]), pathlib.Path(sys.argv[2]), sys.argv[3:])
