"""Avalanche statistics of silo discharges (Pérez Sec. 4) and their sweep summary.

For each hole size R = d_h/d_ave: the mean avalanche size <s> with its standard error
(null avalanches included, the first avalanche of each run, the initial discharge, left
out), the probability of a null avalanche, the normalized cumulative w(s) (Pérez Eq. 39)
and the mean flow rate.  Across R, <s>(R) fitted (weighted by the standard errors) to

    <s> = s0 exp(B R^2)               and        <s> = s0 / (R_c - R)^gamma,

with parameter uncertainties from the covariance and chi^2 per degree of freedom.
Pérez reports s0 = 1.64 +- 0.08, B = 0.0716 +- 0.0006 and s0 = 8.5e5, R_c = 6.7 +- 0.4,
gamma = 8.2 +- 1.1; the summary fits graindyn's own points and prints both beside them.
He also gives <s> = 50.4 at R = 3.4 and 1385.3 at 4.5 (Fig. 6 caption), and a null
fraction of 0.20 at R = 3.4 down to 0.019 at 4.4: the summary sets each hole's numbers
beside his power law there and draws his points with graindyn's.

The avalanches of one run are not independent of each other (null avalanches come in
runs, Pérez Sec. 4; one packing's history runs through them all), so beside the
standard error of the pooled sizes each row carries the seed-to-seed one: the spread of
the runs' own means over the square root of their number.
"""
import json
import math
import pathlib

import numpy as np
from scipy.optimize import curve_fit

from .flow import beverloo, fit_beverloo

PAPER = {"exp_square": {"s0": 1.64, "B": 0.0716},
         "power_law": {"s0": 8.5e5, "R_c": 6.7, "gamma": 8.2}}
# Pérez's measured points (R: value): the Fig. 6 caption's <s> and the null fractions
# of Sec. 4
PAPER_MEAN_SIZE = {3.4: 50.4, 4.5: 1385.3}
PAPER_NULL_FRACTION = {3.4: 0.20, 4.4: 0.019}


def statistics(sizes):
    """count, mean size, its standard error, null fraction of avalanche ``sizes``."""
    s = np.asarray(sizes, dtype=float)
    out = {"count": int(s.size), "null": int(np.sum(s == 0))}
    if s.size:
        out["mean"] = float(np.mean(s))
        out["mean_err"] = float(np.std(s, ddof=1) / math.sqrt(s.size)) if s.size > 1 \
            else float("nan")
        out["null_fraction"] = float(np.mean(s == 0))
    return out


def exp_square(R, s0, B):
    return s0 * np.exp(B * np.asarray(R) ** 2)


def power_law(R, s0, R_c, gamma):
    return s0 / np.abs(R_c - np.asarray(R)) ** gamma


def _fit(model, R, mean, err, start, names):
    """curve_fit of ``model`` to mean(R) weighted by err: parameters, errors, chi2/dof."""
    R, mean, err = (np.asarray(a, dtype=float) for a in (R, mean, err))
    dof = R.size - len(start)
    if dof < 1:
        return {"error": f"{R.size} points cannot fit {len(start)} parameters"}
    try:
        p, cov = curve_fit(model, R, mean, p0=start, sigma=err, absolute_sigma=True,
                           maxfev=20000)
    except (RuntimeError, ValueError) as failure:
        return {"error": str(failure)}
    chi2 = float(np.sum(((model(R, *p) - mean) / err) ** 2))
    out = {"chi2_per_dof": chi2 / dof, "dof": dof}
    for k, name in enumerate(names):
        out[name] = float(p[k])
        out[f"{name}_err"] = float(math.sqrt(cov[k, k])) if np.isfinite(cov[k, k]) \
            else float("nan")
    return out


def fit_exp_square(R, mean, err):
    """<s> = s0 exp(B R^2), fitted on log-linear start values."""
    R = np.asarray(R, dtype=float)
    B, log_s0 = np.polyfit(R**2, np.log(mean), 1)
    return _fit(exp_square, R, mean, err, (math.exp(log_s0), B), ("s0", "B"))


def fit_power_law(R, mean, err):
    """<s> = s0/(R_c - R)^gamma, from R_c = max(R) + 1 and a log-log start."""
    R = np.asarray(R, dtype=float)
    best = None
    for R_c in R.max() + np.array([0.5, 1.0, 2.0, 4.0]):
        slope, log_s0 = np.polyfit(np.log(R_c - R), np.log(mean), 1)
        fit = _fit(power_law, R, mean, err, (math.exp(log_s0), R_c, -slope),
                   ("s0", "R_c", "gamma"))
        if "error" not in fit and fit["R_c"] > R.max() and (
                best is None or fit["chi2_per_dof"] < best["chi2_per_dof"]):
            best = fit
    return best or {"error": "no power law with R_c above the largest R fits"}


def paper_shifted(R, shift):
    """Pérez's power law at R + shift (his s0, R_c and gamma): his curve moved along R."""
    law = PAPER["power_law"]
    return power_law(np.asarray(R) + shift, law["s0"], law["R_c"], law["gamma"])


def fit_paper_shift(R, mean, err):
    """The shift along R that lays Pérez's power law on graindyn's <s>(R), the one
    parameter fitted (weighted by err): <s>(R) = P(R + shift).  A chi^2 per degree of
    freedom near 1 says the two grow alike and differ by an offset in the hole size
    alone (a hole that acts wider or narrower than its width by shift d_ave)."""
    return _fit(paper_shifted, R, mean, err, (0.0,), ("shift",))


def cumulative(sizes):
    """Pérez Eq. 39: w(s) = (number of avalanches of size >= s) / (number of size >= 1)
    for s = 1..max, null avalanches left out; returns (s, w)."""
    positive = np.sort(np.asarray(sizes, dtype=float)[np.asarray(sizes) > 0])
    if positive.size == 0:
        return np.array([]), np.array([])
    s = np.arange(1, int(positive[-1]) + 1)
    return s, (positive.size - np.searchsorted(positive, s, side="left")) / positive.size


def _run_sizes(results):
    """The sizes of a run's avalanches after its first."""
    return [a["size"] for a in results["avalanches"] if not a["first"]]


def _run_cost(results):
    """(simulated seconds of discharge per avalanche, the first included; CPU seconds
    per simulated second in the run's last session) of one run, NaN where the run
    does not say (a run resumed from a checkpoint reports the CPU time of its last
    session and the steps of that session alike, so their ratio stands)."""
    settled = results.get("settle", {}).get("time_s", 0.0)
    count = len(results["avalanches"])
    per_avalanche = (results.get("time_s", float("nan")) - settled) / count if count \
        else float("nan")
    steps = results.get("steps_this_session", 0) * results.get("dt_s", 0.0)
    cpu = results.get("cpu_time_this_session_s", float("nan")) / steps if steps > 0 \
        else float("nan")
    return per_avalanche, cpu


def _finite_mean(values):
    """The mean of the finite ``values``, NaN when there are none."""
    finite = [v for v in values if math.isfinite(v)]
    return sum(finite) / len(finite) if finite else float("nan")


def hole_rows(points):
    """One row per point of a sweep's finished silo points (seeds pooled: the runs of
    one folder of the sweep directory, ``name`` = folder/seed-k), in order of R: the
    folder (``point``), R,
    the statistics of the avalanches after each run's first, each run's mean size
    (in order of the runs' names) with the seed-to-seed standard error of their mean
    (``seed_err``, NaN below two runs), the largest avalanche, the standard error of
    the null fraction (binomial), the mean flow rate, the cost (simulated seconds per
    avalanche, CPU seconds per simulated second and their product, means over the
    runs: _run_cost) and the sizes themselves.  Each
    run measures R = d_h / d_ave with its own mean diameter, which differs from seed
    to seed by about 1e-3 R: a row's R is their mean."""
    grouped, seen = {}, set()
    for p in sorted(points, key=lambda p: p.name):
        if p.status == "finished" and p.results and p.name not in seen:
            seen.add(p.name)
            grouped.setdefault(p.name.rsplit("/", 1)[0], []).append(p.results)
    rows = []
    for point, runs in sorted(grouped.items(),
                              key=lambda item: np.mean([r["R"] for r in item[1]])):
        sizes = [s for r in runs for s in _run_sizes(r)]
        rates = [r["mean_flow_rate_per_s"] for r in runs if "mean_flow_rate_per_s" in r]
        seed_means = [float(np.mean(_run_sizes(r))) for r in runs if _run_sizes(r)]
        stats = statistics(sizes)
        per_avalanche, cpu = (_finite_mean(values) for values in zip(*map(_run_cost, runs)))
        null = stats.get("null_fraction", float("nan"))
        rows.append({"point": point, "R": float(np.mean([r["R"] for r in runs])),
                     "runs": len(runs),
                     **stats, "seed_means": seed_means,
                     "seed_err": float(np.std(seed_means, ddof=1) / math.sqrt(len(seed_means)))
                     if len(seed_means) > 1 else float("nan"),
                     "largest": int(max(sizes)) if sizes else 0,
                     "null_fraction_err": math.sqrt(null * (1.0 - null) / len(sizes))
                     if sizes else float("nan"),
                     "simulated_s_per_avalanche": float(per_avalanche),
                     "cpu_s_per_simulated_s": float(cpu),
                     "cpu_s_per_avalanche": float(per_avalanche * cpu),
                     "flow_rate_per_s": float(np.mean(rates)) if rates else float("nan"),
                     "flow_rate_err": float(np.std(rates, ddof=1) / math.sqrt(len(rates)))
                     if len(rates) > 1 else float("nan"),
                     "d_ave_m": runs[0].get("d_ave_m"),
                     "g_m_per_s2": runs[0].get("g_m_per_s2"),
                     "sizes": sizes})
    return rows


def flow_fit(rows):
    """The Beverloo fit (analysis.flow.fit_beverloo) of the mean flow rates of the holes
    that never jammed (Beverloo's law is one of steady flow; a hole that jams flows in
    bursts), weighted by their seed-to-seed standard errors when every row has one."""
    rows = [r for r in rows if r["count"] == 0]
    return fit_beverloo([r["R"] for r in rows], [r["flow_rate_per_s"] for r in rows],
                        [r["flow_rate_err"] for r in rows],
                        d=rows[0]["d_ave_m"] if rows else None,
                        g=rows[0]["g_m_per_s2"] if rows else None)


def summarize_sweep(sweep_dir, points):
    """Write silo_sweep.md, silo_sweep.json and the figures of <s>(R) with both fits
    and of the collapse of w(s) against s/<s> (Pérez Figs. 6-7); returns the paths."""
    sweep_dir = pathlib.Path(sweep_dir)
    rows = hole_rows(points)
    usable = [r for r in rows if r.get("count", 0) > 1 and r["mean"] > 0
              and np.isfinite(r["mean_err"]) and r["mean_err"] > 0]
    R = [r["R"] for r in usable]
    mean = [r["mean"] for r in usable]
    err = [r["mean_err"] for r in usable]
    holes = len({round(x, 2) for x in R})
    if holes < len(R):      # another parameter varies at one hole: no curve across R
        shared = {"error": "points share a hole size (another parameter varies)"}
        fits = {"exp_square": shared, "power_law": shared, "paper_shift": shared}
    else:
        fits = {"exp_square": fit_exp_square(R, mean, err) if holes > 2 else
                {"error": "fewer than 3 hole sizes"},
                "power_law": fit_power_law(R, mean, err) if holes > 3 else
                {"error": "fewer than 4 hole sizes"},
                "paper_shift": fit_paper_shift(R, mean, err) if holes > 1 else
                {"error": "fewer than 2 hole sizes"}}
    fits.update(paper=PAPER, beverloo=flow_fit(rows))
    paper = PAPER["power_law"]
    lines = ["# Avalanches of the 2D silo against the hole size (Pérez Sec. 4)", "",
             "<s>: mean size, null avalanches included, +- the standard error of the pooled "
             "sizes, then +- the seed-to-seed one (the spread of the runs' means over "
             "sqrt(runs)); null: count (fraction +- binomial error); Pérez: his power law "
             "at R (his measured <s>: 50.4 at R = 3.4, 1385.3 at 4.5; null fraction 0.20 at "
             "3.4, 0.019 at 4.4).  Cost: simulated seconds of discharge per avalanche and "
             "CPU seconds per avalanche (that times the CPU seconds per simulated second "
             "of the runs, on their machine and its load).", "",
             "| point | R | runs | avalanches | <s> | seed means | null | largest s | "
             "flow rate [disks/s] | Pérez <s> | sim. s / avalanche | CPU s / avalanche |",
             "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        mean = r.get("mean", float("nan"))
        lines.append(
            f"| {r['point']} | {r['R']:.3f} | {r['runs']} | {r['count']} | {mean:.1f} +- "
            f"{r.get('mean_err', float('nan')):.1f} +- {r['seed_err']:.1f} | "
            + ", ".join(f"{m:.1f}" for m in r["seed_means"])
            + f" | {r['null']} ({r.get('null_fraction', float('nan')):.3f} +- "
            f"{r['null_fraction_err']:.3f}) | {r['largest']} | "
            f"{r['flow_rate_per_s']:.1f} +- {r['flow_rate_err']:.1f} | "
            f"{float(power_law(r['R'], paper['s0'], paper['R_c'], paper['gamma'])):.0f} | "
            f"{r['simulated_s_per_avalanche']:.2f} | {r['cpu_s_per_avalanche']:.0f} |")
    lines += ["", "Fits of <s>(R), weighted by the standard errors of the pooled sizes:", ""]
    for name in ("exp_square", "power_law"):
        paper = ", ".join(f"{k} = {v}" for k, v in PAPER[name].items())
        lines.append(_fit_line(name, fits[name], lambda f, name=name: ", ".join(
            f"{k} = {f[k]:.4g} +- {f[k + '_err']:.2g}" for k in PAPER[name])
            + f", chi2/dof = {f['chi2_per_dof']:.3g}") + f"; Pérez: {paper}")
    lines.append(_fit_line(
        "Pérez's power law moved along R, <s> = P(R + shift)", fits["paper_shift"],
        lambda f: f"shift = {f['shift']:.3f} +- {f['shift_err']:.2g}, "
                  f"chi2/dof = {f['chi2_per_dof']:.3g}"))
    lines.append(_fit_line(
        "flow rate, Q = A (R - k)^(3/2) (Beverloo in 2D)", fits["beverloo"],
        lambda f: f"A = {f['A']:.4g} +- {f['A_err']:.2g} disks/s, k = {f['k']:.3g} +- "
                  f"{f['k_err']:.2g}"
                  + (f", C = A sqrt(d/g) = {f['C']:.3g} +- {f['C_err']:.2g}" if "C" in f else "")
                  + (f", chi2/dof = {f['chi2_per_dof']:.3g}" if "chi2_per_dof" in f else "")))
    md = sweep_dir / "silo_sweep.md"
    md.write_text("\n".join(lines) + "\n")
    js = sweep_dir / "silo_sweep.json"
    js.write_text(json.dumps({"rows": rows, "fits": fits}, indent=1, default=float))
    return [md, js, _figure(sweep_dir / "figures" / "silo_sweep.png", rows, usable, fits)]


def _fit_line(label, fit, values):
    """A line of the summary: the fit's values (``values(fit)``), or why it was not
    fitted."""
    if "error" in fit:
        return f"- {label}: not fitted ({fit['error']})"
    return f"- {label}: {values(fit)}"


def _paper_sizes(ax):
    """Pérez's <s>(R) on ``ax`` (log scale): his two measured points and his two fits
    over R = 3.4-4.5 as he prints them (the exp(B R^2) one misses his own points)."""
    grid = np.linspace(3.4, 4.5, 100)
    law, square = PAPER["power_law"], PAPER["exp_square"]
    ax.plot(grid, power_law(grid, law["s0"], law["R_c"], law["gamma"]), "k:", lw=1,
            label="Pérez: power law")
    ax.plot(grid, exp_square(grid, square["s0"], square["B"]), color="0.6", ls="-.", lw=1,
            label="Pérez: s0 exp(B R^2)")
    ax.plot(list(PAPER_MEAN_SIZE), list(PAPER_MEAN_SIZE.values()), "k*", ms=9,
            label="Pérez: measured")
    ax.set_yscale("log")


def _figure(path, rows, usable, fits):
    from ..figures import subplots

    fig, ax = subplots(1, 4, figsize=(20, 4.2))
    for r in rows:
        s, w = cumulative(r["sizes"])
        if s.size and r.get("mean", 0) > 0:
            ax[0].semilogy(s / r["mean"], w, ".", ms=3, label=f"R = {r['R']:.2f}")
    ax[0].set(xlabel="s / <s>", ylabel="w(s) (Eq. 39)", title="collapse (Pérez Fig. 6)")
    if usable:
        R = np.array([r["R"] for r in usable])
        ax[1].errorbar(R, [r["mean"] for r in usable], [r["mean_err"] for r in usable],
                       fmt="o", label="graindyn")
        grid = np.linspace(R.min(), R.max(), 100)
        if "error" not in fits["exp_square"]:
            f = fits["exp_square"]
            ax[1].plot(grid, exp_square(grid, f["s0"], f["B"]), label="fit: s0 exp(B R^2)")
        if "error" not in fits["power_law"]:
            f = fits["power_law"]
            ax[1].plot(grid, power_law(grid, f["s0"], f["R_c"], f["gamma"]), "--",
                       label="fit: s0 / (R_c - R)^gamma")
    if "error" not in fits["paper_shift"]:
        shift = fits["paper_shift"]["shift"]
        grid = np.linspace(3.4, 4.5, 100)
        ax[1].plot(grid, paper_shifted(grid, shift), "k--", lw=1, alpha=0.5,
                   label=f"Pérez's law at R {shift:+.2f}")
    _paper_sizes(ax[1])
    ax[1].set(xlabel="R = d_h / d_ave", ylabel="<s>", title="Pérez Fig. 7")
    counted = [r for r in rows if r.get("count", 0) > 0]
    if counted:
        ax[2].errorbar([r["R"] for r in counted], [r["null_fraction"] for r in counted],
                       [r["null_fraction_err"] for r in counted], fmt="o", label="graindyn")
    ax[2].plot(list(PAPER_NULL_FRACTION), list(PAPER_NULL_FRACTION.values()), "k*", ms=9,
               label="Pérez")
    ax[2].set(xlabel="R = d_h / d_ave", ylabel="fraction of null avalanches",
              title="null avalanches")
    flowing = [r for r in rows if np.isfinite(r["flow_rate_per_s"])]
    if flowing:
        R = np.array([r["R"] for r in flowing])
        ax[3].errorbar(R, [r["flow_rate_per_s"] for r in flowing],
                       [r["flow_rate_err"] for r in flowing], fmt="o", label="graindyn")
        fit = fits["beverloo"]
        if "error" not in fit:
            grid = np.linspace(max(fit["k"], 0.0), R.max(), 100)
            ax[3].plot(grid, beverloo(grid, fit["A"], fit["k"]),
                       label=f"A (R - k)^1.5, k = {fit['k']:.2f}")
    ax[3].set(xlabel="R = d_h / d_ave", ylabel="flow rate [disks/s]",
              title="discharge rate (Beverloo)")
    for a in ax:
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
