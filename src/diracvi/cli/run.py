"""``diracvi list`` and ``diracvi run``: the built-in problems, and one simulation (a problem, a
model file, a SPICE netlist or a URDF robot) summarized."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..discretization.names import BUILT_IN as RULE_NAMES
from ..driver.step_error import ERRORS as STEP_ERRORS
from .common import (
    EXIT_USAGE,
    SOLVERS,
    _choice,
    _fail,
    _library_errors,
    _note,
    _out,
    _positive_float,
    _positive_int,
    _resolve_model,
    _rule_names,
    _settle,
    _solver_option,
    is_netlist,
)


def _tolerance(name: str, what: str):
    """A ``--reltol``-like option: a netlist's ``.options`` value, replaced for this run."""
    return typer.Option(
        callback=_positive_float,
        metavar="FLOAT",
        help=f"A netlist's {what}, in place of its .options {name} (the deck unedited).",
    )


def list_problems() -> None:
    """List the built-in problems (names for `diracvi run`)."""
    from .. import problems

    table = Table(title="diracvi built-in problems", title_justify="left")
    table.add_column("name", style="bold", no_wrap=True)
    table.add_column("description")
    for name, description in problems.available().items():
        table.add_row(name, description)
    _out().print(table)


def run(
    problem: Annotated[
        str,
        typer.Argument(
            help="A built-in problem (see `diracvi list`), a model file path/to/model.py "
            "defining build() -> (system, q0, p0) or a dict with system, q0, p0, and "
            "optionally dt, steps, or a SPICE netlist (.cir, .sp, .spice, .net, .ckt, .spi, "
            ".cir.out; "
            "run as SPICE does: variable steps, output every TSTEP from TSTART, or a fixed "
            "step with --dt; the NetCDF holds v(<node>) and i(<element>)), or a URDF robot "
            "(.urdf; fixed base, released from rest under gravity, 2000 steps of 1 ms by "
            "default; the NetCDF holds joint_position, body_position, body_orientation, "
            "body_angles).",
            show_default=False,
        ),
    ],
    dt: Annotated[
        str | None,
        typer.Option(
            callback=_positive_float,
            metavar="FLOAT",
            help="Step size h, SPICE suffixes allowed (5u) (default: the problem's).",
        ),
    ] = None,
    steps: Annotated[
        str | None,
        typer.Option(
            callback=_positive_int, metavar="INT", help="Number of steps (default: the problem's)."
        ),
    ] = None,
    scheme: Annotated[
        str,
        typer.Option(
            callback=_choice(("plus", "minus")),
            metavar="plus|minus",
            help="(+) forward or (−) backward discrete Dirac equations.",
        ),
    ] = "plus",
    discretization: Annotated[
        str | None,
        typer.Option(
            callback=_choice(_rule_names),
            metavar="|".join(RULE_NAMES),
            help="Quadrature rule (default: the problem's first solvable one, usually retraction).",
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Save the trajectory as NetCDF (e.g. run.nc).")
    ] = None,
    plot: Annotated[
        bool, typer.Option("--plot", help="Also write a PNG plot next to --out (or ./NAME.png).")
    ] = False,
    raw: Annotated[
        Path | None,
        typer.Option(help="Also write an ngspice raw file of a netlist's saved vectors."),
    ] = None,
    solver: Annotated[
        str | None,
        typer.Option(
            callback=_choice(SOLVERS),
            metavar="|".join(SOLVERS),
            help="Step solver of a fixed-step run (default: automatic — the affine map for "
            "linear models, else Newton reusing its Jacobian). newton-full recomputes the "
            "Jacobian every iteration; partitioned suits large interconnections.",
        ),
    ] = None,
    reltol: Annotated[str | None, _tolerance("reltol", "relative tolerance")] = None,
    abstol: Annotated[str | None, _tolerance("abstol", "current tolerance (A)")] = None,
    vntol: Annotated[str | None, _tolerance("vntol", "voltage tolerance (V)")] = None,
    chgtol: Annotated[str | None, _tolerance("chgtol", "charge tolerance (C)")] = None,
    tmax: Annotated[
        str | None,
        typer.Option(
            callback=_positive_float,
            metavar="FLOAT",
            help="A netlist's largest step TMAX (s), in place of its .tran's (the deck "
            "unedited); SPICE suffixes allowed (20p).",
        ),
    ] = None,
    step_error: Annotated[
        str | None,
        typer.Option(
            callback=_choice(STEP_ERRORS),
            metavar="|".join(STEP_ERRORS),
            help="How a linear netlist's variable steps on the sparse maps are judged: "
            "doubling (each try one step against two of half its size, three solves) or "
            "truncation (one solve a step, its local truncation error from the past "
            "steps). Default: spice.run's. A circuit the compiled loop steps (nonlinear, "
            "switched, fewer than 16 coordinates) is judged by step doubling either way.",
        ),
    ] = None,
) -> None:
    """Simulate a built-in problem or a model file and print a short summary."""
    tolerances = dict(reltol=reltol, abstol=abstol, vntol=vntol, chgtol=chgtol, tmax=tmax)
    tolerances = {k: v for k, v in tolerances.items() if v is not None}
    if step_error is not None:  # (spice.run's keyword; the CLI spells it --step-error)
        tolerances["step_error"] = step_error
    if tolerances and not is_netlist(problem):
        given = " ".join(f"--{k.replace('_', '-')}" for k in tolerances)
        _fail(
            f"{given}: a SPICE netlist's variable-step settings; {problem!r} is not a netlist.",
            EXIT_USAGE,
        )
    for flag, target in (("--out", out), ("--raw", raw)):
        if target is not None and not target.parent.exists():
            _fail(
                f"{flag} {str(target)!r}: folder {str(target.parent)!r} does not exist.", EXIT_USAGE
            )
    if Path(problem).suffix.lower() == ".urdf":  # a robot: released from rest under gravity
        if raw is not None:
            _fail(
                f"--raw writes a SPICE netlist's vectors; {problem!r} is a URDF robot.", EXIT_USAGE
            )
        _run_urdf(Path(problem), dt, steps, scheme, discretization, out, plot, solver)
        return
    model = _resolve_model(problem)
    if raw is not None and not hasattr(model, "assembly"):
        _fail(f"--raw writes a SPICE netlist's vectors; {problem!r} is not a netlist.", EXIT_USAGE)
    if hasattr(model, "assembly"):  # a netlist: SPICE's time semantics (see spice.run)
        _run_netlist(model, dt, steps, scheme, discretization, out, plot, raw, solver, tolerances)
        return
    h = dt if dt is not None else getattr(model, "dt", None)
    n_steps = steps if steps is not None else getattr(model, "steps", None)
    if h is None or n_steps is None:
        missing = " and ".join(o for o, v in (("--dt", h), ("--steps", n_steps)) if v is None)
        _fail(
            f"model file {problem!r} sets no default for {missing}: pass {missing} or "
            "return dt/steps from build().",
            EXIT_USAGE,
        )
    rules = tuple(getattr(model, "discretizations", ("retraction", "midpoint")))
    rule = discretization or rules[0]
    if rule not in rules:
        _note(f"note: {model.name!r} lists only {rules} as solvable; trying {rule!r} anyway.")

    from .. import simulate

    with _library_errors(partial_out=out):
        traj = simulate(
            model.system,
            model.q0,
            model.p0,
            dt=h,
            steps=n_steps,
            scheme=scheme,
            discretization=rule,
            t0=getattr(model, "t0", 0.0),
            solver=_solver_option(solver),
        )
    _print_summary(model.name, traj)
    notes = getattr(model, "notes", ())
    for note in [notes] if isinstance(notes, str) else notes:  # one note, or a list of them
        _note(f"note: {note}")
    if out is not None:
        with _library_errors():
            traj.save(out)
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)
    if plot:
        from ..plotting import plot_trajectory

        png = out.with_suffix(".png") if out is not None else Path(f"{model.name}.png")
        plot_trajectory(traj, png, name=model.name)
        _out().print(f"wrote {png}", markup=False, soft_wrap=True)


#: ``diracvi run robot.urdf``: the robot on its fixed base, every joint at 0 and at rest,
#: falls under MuJoCo's gravity for 2000 steps of 1 ms (2 s, the MuJoCo check's span)
URDF_DT, URDF_STEPS = 1e-3, 2000
#: the rules a URDF robot steps with (the retraction rule drifts in a rigid body's energy)
URDF_RULES = ("midpoint", "lobatto")


def _run_urdf(path: Path, dt, steps, scheme, discretization, out, plot, solver) -> None:
    """Read, build and simulate ``path``; print the summary and the final joint values."""
    if not path.is_file():
        _fail(f"URDF file {str(path)!r} does not exist.", EXIT_USAGE)
    rule = discretization or URDF_RULES[0]
    if rule not in URDF_RULES:
        _fail(
            f"--discretization {rule}: a URDF robot steps with {' or '.join(URDF_RULES)} "
            "(the retraction rule does not keep a rigid body's energy bounded).",
            EXIT_USAGE,
        )
    from .. import simulate
    from ..components.urdf import read_urdf

    with _library_errors():
        robot = read_urdf(path, quiet=True)
        model = robot.build()
    with _library_errors(partial_out=out):
        traj = simulate(
            model.system,
            model.q0,
            model.p0,
            dt=URDF_DT if dt is None else dt,
            steps=URDF_STEPS if steps is None else steps,
            scheme=scheme,
            discretization=rule,
            solver=_solver_option(solver),
        )
    name = robot.urdf.name
    _print_summary(name, traj)
    joints = model.coordinate_joints()
    if joints and traj.q is not None:
        final = ", ".join(f"{j} {float(model.joint_position(traj.q, j)[-1]):.6g}" for j in joints)
        _out().print(f"final joints: {final}", markup=False, soft_wrap=True)
    for note in robot.urdf.notes:
        _note(f"note: {note} (diracvi models no joint limits, friction or coupling)")
    if out is None and not plot:
        return
    with _library_errors():
        ds = model.dataset(traj)  # the motion by name: joints, body positions, orientations
    if out is not None:
        with _library_errors():
            traj.save(out, dataset=ds)
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)
    if plot:
        from ..plotting import plot_joints

        png = out.with_suffix(".png") if out is not None else Path(f"{name}.png")
        kinds = {j: model.joints[j].kind for j in joints}
        plot_joints(
            traj.t,
            {j: ds["joint_position"].sel(joint=j).values for j in joints},
            kinds,
            png,
            title=f"{name} ({path.name}): released from rest",
        )
        _out().print(f"wrote {png}", markup=False, soft_wrap=True)


def _run_netlist(
    netlist, dt, steps, scheme, discretization, out, plot, raw, solver, tolerances
) -> None:
    """``diracvi run deck.cir``: variable steps and output every TSTEP from TSTART (at the
    deck's tolerances and TMAX, or ``--reltol`` … ``--tmax``), or a fixed step ``--dt`` to
    TSTOP (``--steps`` alone: the netlist's TSTEP, that many)."""
    from .. import spice

    if scheme != "plus":
        _fail("--scheme minus: a netlist runs forward from its initial state.", EXIT_USAGE)
    fixed = dt is not None or steps is not None
    if solver is not None and not fixed:
        _fail(
            f"--solver {solver}: SPICE's variable steps have their own Newton solve; pass "
            "--dt STEP for a fixed-step run with this solver.",
            EXIT_USAGE,
        )
    if tolerances and fixed:
        given = " ".join(f"--{k.replace('_', '-')}" for k in tolerances)
        _fail(
            f"{given}: tolerances, TMAX and the error control steer SPICE's variable steps; "
            "a fixed step "
            "(--dt/--steps) has none. Leave out one or the other.",
            EXIT_USAGE,
        )
    options = {} if solver is None else {"solver": _solver_option(solver)}
    options.update(tolerances)
    _settle()  # the modules and the read netlist: not walked by the run's collections
    with _library_errors(partial_out=out if fixed else None):
        result = spice.run(
            netlist,
            dt=dt,
            steps=steps,
            discretization=discretization or "midpoint",
            **options,
        )
    if fixed:
        _print_summary(netlist.name, result.trajectory)
    else:
        _print_variable_summary(netlist, result)
    with _library_errors():
        measurements = result.measurements
    for line in measurements:  # as ngspice prints them, after the run
        _out().print(str(line), markup=False, soft_wrap=True)
    for note in netlist.notes:
        _note(f"note: {note}")
    if out is not None:
        with _library_errors():
            result.save(out)
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)
    if raw is not None:
        with _library_errors():
            spice.write_raw(result, raw)
        _out().print(f"wrote {raw}", markup=False, soft_wrap=True)
    if plot:
        from ..plotting import plot_waveforms

        png = out.with_suffix(".png") if out is not None else Path(f"{netlist.name}.png")
        plot_waveforms(result.time, result.waveforms, png, title=netlist.title)
        _out().print(f"wrote {png}", markup=False, soft_wrap=True)


def _print_variable_summary(netlist, result) -> None:
    march, settings = result.trajectory, result.settings
    table = Table(show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold")
    table.add_column()
    rows = [
        ("problem", netlist.name),
        ("scheme", "plus, midpoint, variable steps"),
        (
            "steps",
            f"{len(march.h)} (h {march.h.min():.3g} … {march.h.max():.3g}, TMAX "
            f"{settings.max_step:.3g}; {march.rejected} of {march.tries} tries rejected)",
        ),
        ("time", f"{march.t[0]:g} → {march.t[-1]:g}"),
        ("output", f"{len(result.time)} points every {settings.step:g} from {settings.start:g}"),
        (
            "tolerances",
            f"reltol {settings.reltol:g}, abstol {settings.abstol:g}, "
            f"vntol {settings.vntol:g}, chgtol {settings.chgtol:g}",
        ),
        ("solver", march.solver),
        ("status", march.message),
    ]
    for key, value in rows:
        table.add_row(key, value)
    _out().print(table)


def _print_summary(name: str, traj) -> None:
    import numpy as np

    residual = float(np.max(np.abs(traj.constraint_residual), initial=0.0))
    table = Table(show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold")
    table.add_column()
    rows = [
        ("problem", name),
        ("scheme", f"{traj.scheme}, {traj.discretization}"),
        ("steps", f"{traj.steps} of {traj.steps_requested}, dt = {traj.dt:g}"),
        ("time", f"{traj.t[0]:g} → {traj.t[-1]:g}"),
        ("energy", f"initial {traj.energy[0]:.10g}, final {traj.energy[-1]:.10g}"),
        ("max |constraint residual|", f"{residual:.3e}"),
        (
            "Newton iterations",
            f"{traj.newton_iterations.sum()} total, "
            f"{traj.newton_iterations.mean():.2f} per step (max {traj.newton_iterations.max()})",
        ),
        ("status", traj.message.splitlines()[0]),
    ]
    for key, value in rows:
        table.add_row(key, value)
    _out().print(table)
