"""The sweep summary of the oedometer protocol ("The study"): Oquendo et al.'s
Tables 2 and 3 (h_s and eta of Bauer's law for each value of each varied micro-
parameter) and the figure h_s versus eta of all points, with the power-law fit
h_s = a eta^b, the Guamo sand experiment and the paper's own fit.

Input: the points of a sweep (``graindyn.sweep.collect``); each finished oedometer run
has ``results["bauer"][measure]`` for the two pressure measures ``vertical`` (the
vertical stress) and ``trace`` (sigma_v + 2 sigma_lateral), each a dict with "e0",
"e0_err", "h_s_Pa", "h_s_err_Pa", "eta", "eta_err", ...

Seeds of one value are combined into the mean and an uncertainty: the larger of the
seed spread (sample standard deviation, ddof = 1) and the propagated fit error of the
mean, sqrt(sum err_i^2) / n.  With one seed that is the fit error.

Written into the sweep directory:

    bauer_vertical.md, bauer_trace.md     the tables, one per varied parameter, then
                                          the seed statistics of every value
    figures/hs_eta_vertical.png, ..._trace.png
    figures/compression.png               e/e0 against the vertical stress, every run,
                                          one colour per value
    bauer_sweep.json                      the rows and the power-law fits
"""
import json
import math
import pathlib

import numpy as np

MEASURES = {"vertical": "the vertical stress sigma_v on the piston",
            "trace": "the trace of the stress sigma_v + 2 sigma_lateral"}
# the ladder column (results["ladder"], ladder.csv) each measure reads
PRESSURE_COLUMNS = {"vertical": "sigma_top_Pa", "trace": "trace_Pa"}
SHORT = {"vertical": "vertical stress", "trace": "trace of the stress"}
# Oquendo et al.: the Guamo sand experiment and their fit over all runs (h_s in MPa)
GUAMO = {"h_s_MPa": 19.1, "h_s_err_MPa": 1.1, "eta": 0.57, "eta_err": 0.01}
PAPER_FIT = {"a_MPa": 0.068, "b": -9.88}


def combine(values, errors):
    """(mean, uncertainty) of one value's seeds: the larger of the sample standard
    deviation and the propagated error of the mean sqrt(sum err^2)/n."""
    values = np.asarray(values, float)
    errors = np.asarray(errors, float)
    n = values.size
    if n == 0:
        return math.nan, math.nan
    spread = float(np.std(values, ddof=1)) if n > 1 else 0.0
    propagated = float(np.sqrt(np.sum(errors**2)) / n)
    return float(np.mean(values)), max(spread, propagated)


def _fit(point, measure):
    """The finite fit of ``measure`` in a finished point's results, or None."""
    if point.status != "finished":
        return None
    fit = (point.results or {}).get("bauer", {}).get(measure)
    if not isinstance(fit, dict):
        return None
    keys = ("h_s_Pa", "h_s_err_Pa", "eta", "eta_err")
    try:
        values = [float(fit[k]) for k in keys]
    except (KeyError, TypeError, ValueError):
        return None
    if not all(math.isfinite(v) for v in values) or values[0] <= 0 or values[2] <= 0:
        return None
    return fit


def rows(points, measure):
    """One row per (parameter, value) of the sweep (reference first): the combined
    eta, h_s [MPa] and e0 with their uncertainties over the seeds."""
    grouped = {}
    for p in points:           # by (parameter, value), in sweep order
        grouped.setdefault(p.group, []).append(p)
    out = []
    for members in grouped.values():
        first = members[0]
        fits = [f for f in (_fit(p, measure) for p in members) if f is not None]
        row = {"parameter": first.parameter, "label": first.label, "value": first.value,
               "display": first.display, "base_value": first.base_value,
               "reference": all(p.is_reference for p in members),
               "directories": [p.name for p in members], "runs": len(members),
               "fitted": len(fits),
               "stopped_early_Pa": [p.results["stopped_early"]["target_Pa"] for p in members
                                    if p.status == "finished" and "stopped_early" in
                                    (p.results or {})]}
        for name, name_err, key, err, scale in (
                ("eta", "eta_err", "eta", "eta_err", 1.0),
                ("h_s_MPa", "h_s_err_MPa", "h_s_Pa", "h_s_err_Pa", 1e-6),
                ("e0", "e0_err", "e0", "e0_err", 1.0)):
            try:
                row[name], row[name_err] = combine([scale * float(f[key]) for f in fits],
                                                   [scale * float(f[err]) for f in fits])
            except (KeyError, TypeError, ValueError):
                row[name], row[name_err] = math.nan, math.nan
        out.append(row)
    return out


def pm(value, error):
    """'value ± error' with the error to two significant digits and the value to the
    same decimal place."""
    if not math.isfinite(value):
        return "–"
    if not math.isfinite(error) or error <= 0:
        return f"{value:.4g}"
    digits = max(0, 1 - int(math.floor(math.log10(error))))
    return f"{value:.{digits}f} ± {error:.{digits}f}"


def _display_scale(members):
    """display/value when the display values are the values times one factor."""
    pairs = [(p.value, p.display) for p in members if isinstance(p.value, (int, float))
             and isinstance(p.display, (int, float)) and p.value != 0]
    if not pairs:
        return None
    ratios = [d / v for v, d in pairs]
    if all(math.isclose(r, ratios[0], rel_tol=1e-6) for r in ratios):
        return ratios[0]
    return None


def _fmt(x):
    if isinstance(x, float):
        return f"{x:.6g}"
    return str(x)


def tables(points, measure, table_rows=None):
    """The markdown tables of one pressure measure: per varied parameter its values
    (and the reference run) with eta ± err and h_s [MPa] ± err."""
    table_rows = rows(points, measure) if table_rows is None else table_rows
    reference = next((r for r in table_rows if r["parameter"] is None), None)
    lines = [f"# Bauer's law over the sweep, pressure = {SHORT[measure]} ({measure})", "",
             f"e/e0 = exp(-(p/h_s)^eta) fitted to each run with p = {MEASURES[measure]}. "
             "Per value: the mean over the seeds ± the larger of the seed spread (sample "
             "standard deviation) and the propagated fit error. 'runs' counts the runs "
             "with a fit of all runs of the value; a ladder stopped early (an overlap above "
             "the limit) is fitted on the levels it reached.", ""]
    parameters = []
    for r in table_rows:
        if r["parameter"] is not None and r["parameter"] not in parameters:
            parameters.append(r["parameter"])
    for parameter in parameters:
        mine = [r for r in table_rows if r["parameter"] == parameter]
        members = [p for p in points if p.parameter == parameter]
        label = mine[0]["label"]
        entries = [(r["value"], r["display"], r, r["reference"]) for r in mine]
        if reference is not None and not any(r["reference"] for r in mine):
            base = mine[0]["base_value"]
            scale = _display_scale(members)
            shown = base * scale if scale is not None and isinstance(base, (int, float)) \
                else base
            entries.append((base, shown, reference, True))
        if all(isinstance(e[0], (int, float)) for e in entries):
            entries.sort(key=lambda e: e[0])
        lines += [f"## {label} ({parameter})", "",
                  f"| {label} | eta | h_s [MPa] | runs |", "|---:|---:|---:|---:|"]
        for _, shown, r, is_ref in entries:
            lines.append(f"| {_fmt(shown)}{' (reference)' if is_ref else ''} | "
                         f"{pm(r['eta'], r['eta_err'])} | "
                         f"{pm(r['h_s_MPa'], r['h_s_err_MPa'])} | {r['fitted']}/{r['runs']}"
                         f"{_stopped(r)} |")
        lines.append("")
    if not parameters and reference is not None:
        lines += ["## reference", "", "| eta | h_s [MPa] | runs |", "|---:|---:|---:|",
                  f"| {pm(reference['eta'], reference['eta_err'])} | "
                  f"{pm(reference['h_s_MPa'], reference['h_s_err_MPa'])} | "
                  f"{reference['fitted']}/{reference['runs']}{_stopped(reference)} |", ""]
    return "\n".join(lines)


def _stopped(row):
    """', ladder stopped at p MPa' for runs whose ladder ended early (overlap limit)."""
    stops = row.get("stopped_early_Pa") or []
    return "".join(f", ladder stopped at {p / 1e6:.3g} MPa" for p in stops)


def unique_rows(table_rows):
    """The rows of distinct runs (a value equal to the reference is the reference row)
    that have a fit: the points of the h_s-eta figure and its power-law fit."""
    seen, out = set(), []
    for r in table_rows:
        key = tuple(r["directories"])
        if key in seen or not r["fitted"]:
            continue
        seen.add(key)
        out.append(r)
    return out


def power_law(table_rows):
    """fit_power_law of h_s [MPa] against eta over the distinct points, weighted by the
    h_s uncertainties when all are positive; (fit or None, message)."""
    from ..analysis.bauer import fit_power_law

    points = unique_rows(table_rows)
    eta = np.array([r["eta"] for r in points])
    h_s = np.array([r["h_s_MPa"] for r in points])
    err = np.array([r["h_s_err_MPa"] for r in points])
    if np.unique(eta).size < 2:
        return None, f"too few points for a power-law fit ({len(points)} with a Bauer fit)"
    weights = err if np.all(np.isfinite(err)) and np.all(err > 0) else None
    try:
        return fit_power_law(eta, h_s, weights), ""
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
        return None, f"power-law fit failed: {error}"


def figure(path, table_rows, fit, measure):
    """h_s [MPa] versus eta on log-log axes: every point with its error bars (marker by
    varied parameter), the fit, the paper's fit and the Guamo sand experiment."""
    import matplotlib.ticker

    from ..figures import save, subplots

    fig, ax = subplots(figsize=(6.4, 4.8))
    markers = "osD^v<>ph"
    points = unique_rows(table_rows)
    labels = []
    for r in points:
        key = "reference" if r["reference"] else r["label"]
        if key not in labels:
            labels.append(key)
    for k, key in enumerate(labels):
        mine = [r for r in points if ("reference" if r["reference"] else r["label"]) == key]
        style = dict(marker="*", color="k", markersize=11) if key == "reference" else \
            dict(marker=markers[k % len(markers)], markersize=6)
        ax.errorbar([r["eta"] for r in mine], [r["h_s_MPa"] for r in mine],
                    xerr=[r["eta_err"] for r in mine], yerr=[r["h_s_err_MPa"] for r in mine],
                    linestyle="none", capsize=2, label=key, **style)
    ax.errorbar([GUAMO["eta"]], [GUAMO["h_s_MPa"]], xerr=[GUAMO["eta_err"]],
                yerr=[GUAMO["h_s_err_MPa"]], marker="s", color="tab:red", markersize=8,
                markerfacecolor="none", capsize=3, linestyle="none",
                label="Guamo sand (experiment)")
    etas = [r["eta"] for r in points] + [GUAMO["eta"]]
    grid = np.geomspace(min(etas) / 1.15, max(etas) * 1.15, 200)
    ax.plot(grid, PAPER_FIT["a_MPa"] * grid ** PAPER_FIT["b"], "--", color="0.5",
            label=f"Oquendo et al.: h_s = {PAPER_FIT['a_MPa']} eta^{PAPER_FIT['b']}")
    if fit is not None:
        ax.plot(grid, fit.a * grid**fit.b, "-", color="tab:blue",
                label=f"fit: h_s = ({fit.a:.3g} ± {fit.a_err:.2g}) "
                      f"eta^({fit.b:.3g} ± {fit.b_err:.2g})")
    ax.set(xscale="log", yscale="log", xlabel="eta [-]", ylabel="h_s [MPa]",
           title=f"h_s versus eta, pressure = {SHORT[measure]}")
    low, high = ax.get_xlim()
    ax.set_xticks([t for t in (0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 2.0)
                   if low <= t <= high])
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.legend(fontsize=7)
    return save(fig, path)


def compression_figure(path, points):
    """e / e_first (the void ratio over that of the first level) against the vertical
    stress on log axes: every finished run's loading levels (open markers where not at
    rest), one colour per (parameter, value), so that the seed spread shows beside the
    differences between values."""
    from ..figures import save, subplots

    fig, ax = subplots(figsize=(6.4, 4.8))
    groups = {}
    for p in points:
        if p.status == "finished" and (p.results or {}).get("ladder"):
            groups.setdefault(p.group, []).append(p)
    for k, members in enumerate(groups.values()):
        first = members[0]
        color = f"C{k % 10}"
        name = "reference" if all(p.is_reference for p in members) else \
            f"{first.label} = {_fmt(first.display)}"
        for n, p in enumerate(members):
            rows = [r for r in p.results["ladder"] if r["branch"] == "loading"]
            stress = np.array([r["sigma_top_Pa"] for r in rows])
            e = np.array([r["void_ratio"] for r in rows]) / rows[0]["void_ratio"]
            rest = np.array([bool(r["at_rest"]) for r in rows])
            ax.plot(stress, e, "-", color=color, lw=0.8, alpha=0.7,
                    label=f"{name} ({len(members)} runs)" if n == 0 else None)
            ax.plot(stress[rest], e[rest], "o", color=color, ms=3)
            ax.plot(stress[~rest], e[~rest], "o", color=color, ms=3, mfc="none")
    ax.set(xscale="log", xlabel="vertical stress [Pa]", ylabel="e / e (first level) [-]",
           title="compression of every run (open: level not at rest)")
    if groups:
        ax.legend(fontsize=7)
    return save(fig, path)




def _finite(data):
    """``data`` with NaN and infinities as None (valid JSON)."""
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def _refit_without_first(results, measure):
    """(eta, h_s [Pa]) of Bauer's law refitted to the levels a run's fit used, its first
    level left out; None when too few remain or the fit fails."""
    from .bauer import BauerFitError, fit_bauer

    fit = results["bauer"][measure]
    levels = list(fit.get("levels") or [])[1:]
    ladder = {r["level"]: r for r in results.get("ladder", [])}
    if len(levels) < 4 or any(level not in ladder for level in levels):
        return None
    try:
        refit = fit_bauer([ladder[v][PRESSURE_COLUMNS[measure]] for v in levels],
                          [ladder[v]["void_ratio"] for v in levels], pressure=measure)
    except BauerFitError:
        return None
    return refit.eta, refit.h_s


def seed_rows(points, measure):
    """Per (parameter, value): over the seeds with a fit, the mean, the seed spread
    (sample standard deviation) and the mean fit error of eta and h_s [MPa] kept
    apart; e0 and K0 (the mean over the fitted levels of each run) with their spread;
    and eta and h_s refitted with the first fitted level left out."""
    grouped = {}
    for p in points:
        grouped.setdefault(p.group, []).append(p)
    out = []
    for members in grouped.values():
        fitted = [(p, f) for p, f in ((p, _fit(p, measure)) for p in members)
                  if f is not None]
        row = {"label": members[0].label, "display": members[0].display,
               "reference": all(p.is_reference for p in members), "runs": len(members),
               "fitted": len(fitted)}

        def stats(name, values, errors=None):
            values = np.asarray(values, float)
            row[name] = float(np.mean(values)) if values.size else math.nan
            row[name + "_spread"] = float(np.std(values, ddof=1)) if values.size > 1 \
                else math.nan
            if errors is not None:
                row[name + "_fit_err"] = float(np.mean(errors)) if len(errors) else math.nan

        stats("eta", [f["eta"] for _, f in fitted], [f["eta_err"] for _, f in fitted])
        stats("h_s_MPa", [1e-6 * f["h_s_Pa"] for _, f in fitted],
              [1e-6 * f["h_s_err_Pa"] for _, f in fitted])
        stats("e0", [f["e0"] for _, f in fitted])
        k0 = []
        for p, f in fitted:
            ladder = {r["level"]: r for r in p.results.get("ladder", [])}
            values = [ladder[v]["K0"] for v in f.get("levels") or [] if v in ladder]
            if values:
                k0.append(np.mean(values))
        stats("K0", k0)
        refits = [r for r in (_refit_without_first(p.results, measure) for p, _ in fitted)
                  if r is not None]
        stats("eta_without_first", [r[0] for r in refits])
        stats("h_s_MPa_without_first", [1e-6 * r[1] for r in refits])
        row["refitted"] = len(refits)
        out.append(row)
    return out


def seed_table(points, measure):
    """The markdown table of seed_rows: each quantity as mean, seed spread and mean fit
    error side by side."""
    lines = ["## Seed to seed", "",
             "Per value, over the seeds with a fit: the mean, the seed spread (sample "
             "standard deviation) and the mean of the fit errors, kept apart; K0 is "
             "each run's mean over its fitted levels; the last two columns refit each "
             "run without its first fitted level.", "",
             "| value | runs | e0 | K0 | eta | eta spread | eta fit error | h_s [MPa] | "
             "h_s spread | h_s fit error | eta, first level out | h_s [MPa], first "
             "level out |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def g(x, digits=3):
        return "–" if not math.isfinite(x) else f"{x:.{digits}g}"

    def spread(r, name):
        """'mean ± spread', the mean alone with one seed, '–' with none."""
        if not math.isfinite(r[name]):
            return "–"
        if not math.isfinite(r[name + "_spread"]):
            return g(r[name])
        return f"{g(r[name])} ± {g(r[name + '_spread'], 2)}"

    for r in seed_rows(points, measure):
        name = "reference" if r["reference"] else f"{r['label']} = {_fmt(r['display'])}"
        lines.append(
            f"| {name} | {r['fitted']}/{r['runs']} | {spread(r, 'e0')} | {spread(r, 'K0')} | "
            f"{g(r['eta'])} | {g(r['eta_spread'], 2)} | {g(r['eta_fit_err'], 2)} | "
            f"{g(r['h_s_MPa'])} | {g(r['h_s_MPa_spread'], 2)} | "
            f"{g(r['h_s_MPa_fit_err'], 2)} | {spread(r, 'eta_without_first')} | "
            f"{spread(r, 'h_s_MPa_without_first')} |")
    return "\n".join(lines) + "\n"


def summarize_sweep(sweep_dir, points):
    """Write the oedometer sweep's tables, figures and bauer_sweep.json into
    ``sweep_dir``; returns their paths."""
    sweep_dir = pathlib.Path(sweep_dir)
    paths, summary = [], {"guamo": GUAMO, "paper_fit": PAPER_FIT, "measures": {}}
    for measure in MEASURES:
        table_rows = rows(points, measure)
        fit, message = power_law(table_rows)
        text = tables(points, measure, table_rows)
        text += "\n## h_s = a eta^b over all points\n\n" + (
            f"a = {pm(fit.a, fit.a_err)} MPa, b = {pm(fit.b, fit.b_err)} "
            f"({len(unique_rows(table_rows))} points)" if fit is not None else message) \
            + (f"\n\nOquendo et al.: h_s = {PAPER_FIT['a_MPa']} eta^{PAPER_FIT['b']} MPa; "
               f"Guamo sand: h_s = {GUAMO['h_s_MPa']} ± {GUAMO['h_s_err_MPa']} MPa, "
               f"eta = {GUAMO['eta']} ± {GUAMO['eta_err']}.\n") \
            + "\n" + seed_table(points, measure)
        path = sweep_dir / f"bauer_{measure}.md"
        path.write_text(text)
        paths.append(path)
        paths.append(figure(sweep_dir / "figures" / f"hs_eta_{measure}.png", table_rows,
                            fit, measure))
        summary["measures"][measure] = {
            "pressure": MEASURES[measure], "rows": table_rows,
            "seed_rows": seed_rows(points, measure),
            "power_law": fit.as_dict() if fit is not None else None,
            "power_law_note": message}
    paths.append(compression_figure(sweep_dir / "figures" / "compression.png", points))
    path = sweep_dir / "bauer_sweep.json"
    path.write_text(json.dumps(_finite(summary), indent=1, default=float))
    paths.append(path)
    return paths
