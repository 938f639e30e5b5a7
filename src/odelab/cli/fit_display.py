"""The terminal's [fit] section for ``odelab run`` (Rich): estimates, intervals, correlations, warnings."""

from __future__ import annotations

from rich.console import Console

from odelab.terminal import shown

__all__ = ["print_fit", "SOLVER_EFFECT_LIMIT"]

SOLVER_EFFECT_LIMIT = 0.01
"""Above this shift of the estimates (in standard errors) caused by the solver, the terminal warns."""


def _num(value, digits: int = 7) -> str:
    if value is None:
        return "-"
    return f"{value:.{digits}g}"


def _solves(fit: dict) -> str:
    if fit.get("jacobian") == "differences":
        return (f"{fit['fmu_runs']} runs of the FMU (the Jacobian by central differences, two runs a parameter "
                "per evaluation)")
    return f"{fit['solves']} solves of states and sensitivities"


def print_fit(console: Console, fit: dict) -> None:
    """Print one experiment's fit summary (``fit_summary``'s dict)."""
    from odelab.cli.grid import print_grid

    ok = fit["status"] == "converged"
    head = "[bold]fit[/]" if ok else "[bold red]fit FAILED[/]"
    noise = "sigma given in \\[data]" if fit["sigma_known"] else "noise estimated from the residuals"
    console.print(f"{head}: {len(fit['names'])} parameter{'' if len(fit['names']) == 1 else 's'} from {fit['n']} measurements "
                  f"({', '.join(shown(q) for q in fit['quantities'])}; {noise}), {fit['iterations']} iterations, "
                  f"{_solves(fit)} ({shown(fit['method'])}, rtol {fit['rtol']:g})")
    failed = fit.get("failed_trials") or 0
    if failed:
        steps = "steps" if failed != 1 else "a step"
        console.print(f"  {failed} trial point{'s' if failed != 1 else ''} where the model could not be solved "
                      f"(blow-up, NaN or max steps): rejected as {steps} of infinite cost, the trust region shrunk")
    if not ok:
        console.print(f"[red]  {shown(fit['message'], lines=True)}[/]")
        return
    columns = [("parameter", "left"), ("estimate", "right"), ("std error", "right"), ("95% interval", "left"),
               ("rel. se", "right"), ("initial", "right")]
    rows = []
    for name, p in fit["parameters"].items():
        est, se = p["estimate"], p["standard_error"]
        lo, hi = p["ci95"]
        interval = "undetermined" if se is None else f"[{_num(lo)}, {_num(hi)}]"
        rel = "-" if se is None or not est else f"{abs(se / est):.2%}"
        bound = " (at bound)" if p["at_bound"] else ""
        rows.append([shown(name), _num(est, 10) + bound, _num(se, 4), interval, rel, _num(p["initial"], 4)])
    print_grid(console, columns, rows)
    dof_text = f"{fit['dof']} degrees of freedom"
    if fit["sigma_known"]:
        chi = fit["rss"] / fit["dof"] if fit["dof"] else None
        console.print(f"[dim]chi-square {_num(fit['rss'], 6)} with {dof_text} (reduced {_num(chi, 4)}; near 1 when "
                      "the model and sigma are right); intervals: estimate +- t(0.975) x se[/]")
    else:
        console.print(f"[dim]residual sum of squares {_num(fit['rss'], 8)}, {dof_text}, residual standard deviation "
                      f"{_num(fit['residual_std'], 6)}; intervals: estimate +- t(0.975, {fit['dof']}) = "
                      f"{_num(fit['t_quantile'], 5)} x se[/]")
    names = fit["names"]
    if len(names) > 1:
        pairs = []
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                c = fit["correlation"][i][j]
                if c is not None:
                    pairs.append((abs(c), f"{shown(names[i])}-{shown(names[j])} {c:+.4f}"))
        pairs.sort(reverse=True)
        more = f" (and {len(pairs) - 6} more in result.json)" if len(pairs) > 6 else ""
        console.print("  correlations: " + ", ".join(text for _, text in pairs[:6]) + more)
    effect = fit.get("solver_effect")
    if effect is not None and effect > SOLVER_EFFECT_LIMIT:
        console.print(f"[yellow]  warning: the solver's error at rtol {fit['rtol']:g} moves the estimates by {effect:.2g} "
                      "of their standard errors: tighten [fit] rtol (100 times smaller).[/]")
    if fit.get("identifiability"):
        console.print(f"[yellow]  warning: {shown(fit['identifiability'], lines=True)}[/]")
    for case, quantities in fit.get("residuals", {}).items():
        for q, info in quantities.items():
            acf = info["autocorrelation"]
            lag1 = acf[1] if len(acf) > 1 else None
            band = 1.96 / info["rows"] ** 0.5 if info.get("rows") else None
            lag = note = ""
            if lag1 is not None:
                lag = f", lag-1 autocorrelation {lag1:+.2f}"
                if band is not None and abs(lag1) > band:
                    note = (f" (outside white noise's +-{band:.2f}: the residuals are correlated, so the model may miss "
                            "a dynamic, and the intervals are optimistic)")
            console.print(f"  residuals of {shown(q)} in {shown(case)}: rms {_num(info['rms'], 4)}{lag}{note}")
    for v in fit.get("validation", []):
        if v["status"] != "success":
            console.print(f"[red]  validation against {shown(v['file'])} failed: {shown(v['message'], lines=True)}[/]")
            continue
        parts = [f"{shown(q)} rms {_num(r, 4)} (fit {_num(v['fit_rms'].get(q), 4)})" for q, r in v["rms"].items()]
        console.print(f"  validation against {shown(v['file'])} ({v['rows']} rows, case {shown(v['case'])}): "
                      + ", ".join(parts))
