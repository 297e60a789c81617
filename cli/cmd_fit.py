"""kukaid fit: identify an axis from logs and write the parameter file."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("fit")
@click.argument("logs", nargs=-1, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--friction", "friction", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Friction experiment log (constant-velocity sweeps); repeatable.")
@click.option("--inertia", "inertia", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Inertia experiment log (sine); repeatable.")
@click.option("--presliding", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Pre-sliding experiment log (Maxwell-slip elements).")
@click.option("--axis", type=int, default=None, help="Axis number (default: the logs' only axis, or 3).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file to write (JSON, kukaid.params/1).")
@click.option("--method", type=click.Choice(["joint", "staged"]), default="joint", show_default=True,
              help="Stribeck fit: joint (all dynamic samples) or staged (the paper's eqs. 2-5).")
@click.option("--friction-model", type=click.Choice(["stribeck", "coulomb-viscous"]), default="stribeck",
              show_default=True)
@click.option("--gravity", type=click.Choice(["cos", "cos+sin", "none"]), default="cos", show_default=True,
              help="Gravity terms: Mx cos q, + My sin q, or none (horizontal/prismatic axis).")
@click.option("--offset", is_flag=True, help="Fit a constant torque offset.")
@click.option("--elements", type=click.IntRange(1, 10), default=3, show_default=True, help="Maxwell-slip elements.")
@click.option("--cutoff", type=float, default=None, help="Low-pass cut-off, Hz (default 5 Hz at KRC rates).")
@click.option("--order", type=click.IntRange(1, 8), default=None, help="Butterworth order (default 3 at KRC rates).")
@click.option("--qd-thr", type=float, default=None, help="Dynamic-mode velocity threshold, rad/s (0.0017).")
@click.option("--edge", type=int, default=None, help="Samples trimmed at both ends (default 5 fs/cutoff).")
@click.option("--decimate", type=click.IntRange(1, 1000), default=1, show_default=True,
              help="Keep every n-th sample after filtering.")
@click.option("--reversal-window", type=float, default=None,
              help="s; dynamic samples this close to a reversal/start/stop are not fitted (default 1.2/cutoff; 0 keeps all).")
@click.option("--diff", type=click.Choice(["central", "spectral"]), default=None,
              help="Differentiation of the filtered position (default central differences).")
@click.option("--bound", "bound", multiple=True, metavar="NAME=LO:HI",
              help="Override a bound, e.g. --bound vs=0:0.1 --bound Fs-Fc=0:5 (empty side = unbounded).")
def command(logs, friction, inertia, presliding, axis, output, method, friction_model, gravity, offset, elements,
            cutoff, order, qd_thr, edge, decimate, reversal_window, diff, bound) -> None:
    """Fit Stribeck friction, Izz/Mx and Maxwell-slip elements from axis logs (HDF5 or CSV)."""
    import math

    from kukaid.errors import FitError
    from kukaid.identify import fit_axis, format_table
    from kukaid.params import save_params
    from kukaid_cli._util import check_outputs, check_suffix

    check_suffix(output, ".json")
    check_outputs([output], [*logs, *friction, *inertia, presliding])
    for name, v, lo in (("--cutoff", cutoff, 0.0), ("--qd-thr", qd_thr, None), ("--reversal-window", reversal_window, None)):
        if v is not None and not (math.isfinite(v) and (v > lo if lo is not None else v >= 0)):
            raise click.BadParameter(f"{v} must be a finite number {'>' if lo is not None else '>='} 0", param_hint=name)
    if edge is not None and edge < 0:
        raise click.BadParameter(f"{edge} must be >= 0", param_hint="--edge")
    bounds = {}
    for b in bound:
        try:
            name, rng = b.split("=", 1)
            lo, hi = rng.split(":", 1)
            bounds[name.strip()] = (float(lo) if lo.strip() else None, float(hi) if hi.strip() else None)
        except ValueError:
            raise FitError(f"--bound '{b}': expected NAME=LO:HI, e.g. vs=0:0.1") from None
    known = ("Izz", "Mx", "My", "offset", "Fc", "Fv", "Fs-Fc", "vs", "delta")
    for name in bounds:
        if name not in known:
            raise FitError(f"--bound {name}: no such parameter (parameters: {', '.join(known)})")
    params = fit_axis(logs=list(logs), friction=list(friction), inertia=list(inertia), presliding=presliding,
                      axis=axis, method=method, friction_model=friction_model, gravity=gravity, offset=offset,
                      n_elements=elements, bounds=bounds or None, cutoff=cutoff, order=order, qd_thr=qd_thr,
                      edge=edge, decimate=decimate, reversal_window=reversal_window, diff=diff)
    save_params(output, params)
    click.echo(format_table(params))
    click.echo(f"{output}: parameters written", err=True)
