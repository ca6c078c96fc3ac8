"""The settlement procedure over several beds: studies pooled into one ensemble.

One study (studies/settlement.py) settles one bed; its procedure replicas are that bed
with one grain moved by nanometres, which the load cycles amplify into independent
arrangements.  Beds settled from other seeds (``--set run.seed=2``) are independent
from the start and cost no more, but each is a study of its own.  ``pool_beds`` takes
the summaries of several such studies, run with the same procedure settings, and
treats every pair (procedure run, full DEM of the same bed) of every study as one
sample of the procedure's error: the bias mean(s_p - s_f) / mean(s_f) at every cycle,
with its standard error (settlement.ensemble), over all the beds.  Full DEM's chaos
(a nanometre moves its settlement by a few per cent over hundreds of cycles,
docs/settlement.md) makes one pair's error mostly noise; the bias of n pairs resolves
the procedure's own error to about spread / sqrt(n).

Each study folder is read from its ``summary.json`` only (paths, CPU times, settings):
nothing is run.  Two folders of the same seed are refused, since their runs are the
same computations to the bit and would be counted twice; so are folders whose
procedure settings, grain count, loading mode or estimator differ.

>>> pool_beds(["runs/study_bed1", "runs/study_bed2"], "runs/pooled")  # doctest: +SKIP
"""
import csv
import json
import pathlib

import numpy as np

from ..analysis.settlement import fit_residual
from .settlement import FULL, REPLICA_TAG, ensemble_figure, ensemble, perturbation_of

SEED = "run.seed"        # the override that makes another bed of the same settings
POOLED = "pooled.json"


def _summary(folder):
    path = pathlib.Path(folder) / "summary.json"
    if not path.is_file():
        raise ValueError(f"{folder}: no summary.json (not a finished settlement study)")
    return json.loads(path.read_text())


def _settings(summary):
    """What must agree between pooled studies: every override but the seed, the grain
    count, the loading mode and the estimator."""
    overrides = {k: v for k, v in summary["overrides"].items() if k != SEED}
    return {"overrides": overrides, "grains": summary["grains"], "mode": summary["mode"],
            "estimator": summary["estimator"]}


def procedure_runs(summary):
    """The procedure runs of a study summary by base name: {run: [run and its
    replicas]} (full DEM and its replicas left out)."""
    runs = {}
    for name in summary["runs"]:
        base = name.rpartition(REPLICA_TAG)[0] if perturbation_of(name) else name
        if base != FULL:
            runs.setdefault(base, []).append(name)
    return runs


def settlement_after_jumps(path, reference, most=15):
    """How the procedure's bed settles in the cycles computed after each jump, against
    full DEM at the same cycles: ``path`` [(cycle, settlement [m], source)] of a
    procedure run, ``reference`` that of full DEM of the same bed (every cycle).  Each
    computed cycle c that follows a reported cycle c - 1 lies some lag = c - e cycles
    after the end e of the last jump (or of the last correction of a jump) before it; for lag = 1..``most``, returns
    {lag: [the run's settlement over those cycles s(c) - s(c - 1), summed; full DEM's
    over the same cycles; how many]} [m, m, -].  With no effect of the jumps on the bed
    the two sums differ only by the chaos of both computations; a ratio below one at
    every lag says the relaxed bed settles more slowly than the bed it stands for."""
    full = {c: s for c, s, _ in reference}
    path = sorted(path)
    sums = {lag: [0.0, 0.0, 0] for lag in range(1, most + 1)}
    end = None
    for (c0, s0, _), (c1, s1, source) in zip(path, path[1:]):
        if source != "computed" or c1 != c0 + 1:
            end = c1
            continue
        if end is None or not 1 <= c1 - end <= most or c0 not in full or c1 not in full:
            continue
        row = sums[c1 - end]
        row[0] += s1 - s0
        row[1] += full[c1] - full[c0]
        row[2] += 1
    return sums


def jumps_of(path):
    """(a, b) of each jump of a procedure ``path`` [(cycle, settlement [m], source)]: a
    the cycle it starts from, b the first cycle after it."""
    path = sorted(path)
    return [(c0, c1) for (c0, _, _), (c1, _, source) in zip(path, path[1:])
            if source != "computed" or c1 != c0 + 1]


def error_shares(path, reference, estimator, window, period):
    """Where the error of a procedure run's extrapolated cycles comes from: ``path`` and
    ``reference`` as in settlement_after_jumps, ``estimator`` the run's law
    (analysis.settlement.LAWS), ``window`` its computed cycles k and ``period`` [s] the
    load's.  For each jump from cycle a to b the run's own window is replayed on full
    DEM's path: the estimator fitted to full DEM's settlement at cycles a - k..a, on
    the loading's clock t = cycle x period as the procedure fits it, and carried to
    b.  Returns, summed over the
    jumps [m]: "extrapolated", the run's increments over the jumps less full DEM's over
    the same cycles; "estimator", the replayed increments less full DEM's (what the
    jumps would add if every window read full DEM's own path: the estimator's share);
    "bed", their difference (what the jumped, relaxed bed's windows read differently
    from full DEM's over the same cycles: the bed's share); and "jumps"."""
    run = {c: s for c, s, _ in path}
    full = {c: s for c, s, _ in reference}
    shares = {"extrapolated": 0.0, "estimator": 0.0, "bed": 0.0, "jumps": 0}
    for a, b in jumps_of(path):
        cycles = np.arange(a - window, a + 1)
        missing = [int(c) for c in cycles if c not in full] + ([b] if b not in full else [])
        if missing:
            raise ValueError(f"the jump {a} -> {b}: full DEM's path lacks cycles "
                             f"{missing} (its window and end)")
        settlement = np.zeros((cycles.size, 1, 3))
        settlement[:, 0, 2] = [full[c] for c in cycles]
        trend = fit_residual(settlement - settlement[0], period * cycles, estimator)
        replayed = float(trend.extrapolate(period * b)[0, 2] - trend.last[0, 2])
        shares["extrapolated"] += (run[b] - run[a]) - (full[b] - full[a])
        shares["estimator"] += replayed - (full[b] - full[a])
        shares["jumps"] += 1
    shares["bed"] = shares["extrapolated"] - shares["estimator"]
    return shares


def pool_beds(folders, out, run=None, at=None):
    """Pool the settlement studies in ``folders`` (module docstring) for the procedure
    run ``run`` (default: the one procedure run every study has, if there is one) into
    ``out``: pooled.json (the folders, their seeds, the settings and the ensemble of
    every pair, settlement.ensemble, with its bias at the cycles ``at``, default five
    evenly spaced up to the last common cycle, and settlement_after_jumps summed over
    the pairs), pooled.csv (one row per pair: study,
    run, reference, settlement of both at the last common cycle and the difference,
    CPU times) and settlement_ensemble.png.  Returns the pooled dict."""
    folders = [pathlib.Path(f) for f in folders]
    if len(folders) < 2:
        raise ValueError("pooling needs at least two study folders")
    summaries = [_summary(f) for f in folders]
    first = _settings(summaries[0])
    seeds = {}
    for folder, summary in zip(folders, summaries):
        settings = _settings(summary)
        if settings != first:
            differ = sorted(k for k in first if first[k] != settings[k])
            if "overrides" in differ:
                keys = set(first["overrides"]) | set(settings["overrides"])
                differ += sorted(k for k in keys if first["overrides"].get(k)
                                 != settings["overrides"].get(k))
            raise ValueError(f"{folder} was run with other settings than {folders[0]} "
                             f"({', '.join(differ)}): its beds are no samples of the "
                             "same procedure")
        seed = summary["overrides"].get(SEED, "the config's")
        if seed in seeds:
            raise ValueError(f"{folder} and {seeds[seed]} hold the same bed (seed {seed}): "
                             "their runs would be counted twice")
        seeds[seed] = folder
    common = set.intersection(*(set(procedure_runs(s)) for s in summaries))
    if run is None:
        if len(common) != 1:
            raise ValueError("name the procedure run to pool: the studies have "
                             f"{', '.join(sorted(common)) or 'none'} in common")
        run = common.pop()
    elif run not in common:
        raise ValueError(f"{run!r} is not a procedure run of every study (common: "
                         f"{', '.join(sorted(common)) or 'none'})")

    records, pairs, paths = {}, [], {}
    for folder, summary in zip(folders, summaries):
        for name in procedure_runs(summary)[run]:
            reference = summary["runs"][name]["reference"]
            keys = []
            for n in (name, reference):
                key = f"{folder.name}/{n}"
                row = summary["runs"][n]
                records[key] = {"path": summary["paths"][n], "cycle": row["cycles"],
                                "cpu_s": row["cpu_s"]}
                paths[key] = summary["paths"][n]
                keys.append(key)
            pairs.append(tuple(keys))
    pooled = ensemble(records, pairs)
    last = pooled["cycle"]
    at = sorted({int(c) for c in (at or np.linspace(last / 5, last, 5).round())
                 if 1 <= c <= last})
    pooled["bias_at"] = {str(c): [pooled["path_bias"][c - 1], pooled["path_bias_se"][c - 1]]
                         for c in at}
    after = {}
    for p, r in pairs:
        for lag, (run_sum, full_sum, count) in settlement_after_jumps(paths[p],
                                                                      paths[r]).items():
            total = after.setdefault(str(lag), [0.0, 0.0, 0])
            total[0] += run_sum
            total[1] += full_sum
            total[2] += count
    pooled["settlement_after_jumps"] = after
    result = {"folders": [str(f) for f in folders],
              "seeds": {str(s): str(f) for s, f in seeds.items()},
              "run": run, "settings": first, "ensemble": pooled}
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / POOLED).write_text(json.dumps(result, indent=1, default=float))
    with open(out / "pooled.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["study", "run", "reference", "cycle", "settlement_run_m",
                         "settlement_reference_m", "difference_m", "cpu_run_s",
                         "cpu_reference_s"])
        for p, r in pairs:
            study, name = p.split("/")
            s_p = float(np.interp(last, *zip(*[(c, s) for c, s, _ in paths[p]])))
            s_f = float(np.interp(last, *zip(*[(c, s) for c, s, _ in paths[r]])))
            writer.writerow([study, name, r.split("/")[1], last, s_p, s_f, s_p - s_f,
                             records[p]["cpu_s"], records[r]["cpu_s"]])
    title = (f"{summaries[0]['grains']} grains, {summaries[0]['mode']} confined, "
             f"{summaries[0]['estimator']}, {len(pairs)} beds from {len(folders)} studies")
    ensemble_figure(out, {"paths": paths, "ensembles": {run: pooled}},
                     lambda name: name, title)
    return result
