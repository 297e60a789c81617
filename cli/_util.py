"""Small helpers shared by the commands: progress bars and output checks."""
from __future__ import annotations

import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterable, Iterator

import click

from kukaid.errors import KukaidError


class AxisNumber(click.IntRange):
    """``--axis``: a KUKA axis number from ``min`` to ``max``; anything else is said as such (click's
    own line was "'x' is not a valid integer range")."""

    def convert(self, value, param, ctx):
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            self.fail(f"'{value}' is not an axis number: give {self.min} to {self.max} (the KUKA axis, as 3)", param, ctx)


class FloatRange(click.FloatRange):
    """click's ``FloatRange``, refusing ``nan``: every comparison with it is false, so click's took it within
    any range (`serve-sim --speed nan` served, `run-admittance --init-move nan` passed the check of the file
    and switched a robot's follower on)."""

    def __init__(self, *args, what: str = "a number", **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.what = what  # said of a nan: "nan is not a position in degrees"

    def convert(self, value, param, ctx):
        v = super().convert(value, param, ctx)
        if math.isnan(v):
            self.fail(f"{value} is not {self.what}", param, ctx)
        return v


#: ``--axis``: a KUKA axis number, 1 to 12 as in a parameter file (which axes a file models is checked
#: with it: :func:`kukaid.identify.fitted.axis_option`)
AXIS = AxisNumber(1, 12)

#: ``--qd-max`` of run-admittance (its reference's speed limit) and krl-follower (the KRC's), deg/s: 8 % of
#: krl-follower's default ``--axis-speed`` (360 deg/s), a whole percentage the KRC's INT $VEL_AXIS takes as it is,
#: so the two defaults agree (30 became 8 % = 28.8 on the KRC, and the reference ran ahead of it)
QD_MAX_DEG = 28.8

#: ``--port`` of the commands that connect to KUKAVARPROXY (a real controller or serve-sim)
PORT = click.option("--port", type=click.IntRange(1, 65535), default=7000, show_default=True,
                    help="kvp: KUKAVARPROXY port.")


#: ``--urdf`` of the commands that read a robot parameter file: where its URDF is now
URDF = click.option("--urdf", type=click.Path(dir_okay=False, path_type=Path), default=None,
                    help="A robot parameter file's URDF, when it is neither where the file says (robot.urdf) nor "
                         "beside the file (a moved project); it must be the URDF the file was fitted with (sha256).")


def given(name: str, ctx: click.Context | None = None) -> bool:
    """Whether the option (parameter ``name``) was given, on the command line or from the environment,
    not left at its default (the current command's, or ``ctx``'s)."""
    from click.core import ParameterSource

    src = (ctx or click.get_current_context()).get_parameter_source(name)
    return src not in (None, ParameterSource.DEFAULT, ParameterSource.DEFAULT_MAP)


def on_terminal() -> bool:
    """Progress is shown only when stderr is a terminal: in a pipe or a log file it is noise, and
    stderr keeps to what went wrong (one line)."""
    return sys.stderr.isatty()


def stages(command: str) -> Callable[[str], None]:
    """Stage lines for a step whose length is not known beforehand: ``stage("fitting")`` prints
    ``kukaid: fit: fitting (2.1 s)`` on stderr, the time since the command started; on a terminal only."""
    import time

    if not on_terminal():
        return lambda text: None
    t0 = time.monotonic()

    def stage(text: str) -> None:
        click.echo(f"kukaid: {command}: {text} ({time.monotonic() - t0:.1f} s)", err=True)

    return stage


@contextmanager
def progress(total: float, label: str) -> Iterator[Callable[[float], None]]:
    """A progress bar on stderr; yields ``update(done)`` taking the absolute amount done.

    Only on a terminal (:func:`on_terminal`)."""
    if not on_terminal():
        yield lambda done: None
        return
    with click.progressbar(length=max(int(total * 1000), 1), label=label, file=sys.stderr,
                           show_eta=True) as bar:
        state = {"pos": 0}

        def update(done: float) -> None:
            pos = min(int(done * 1000), bar.length)
            if pos > state["pos"]:
                bar.update(pos - state["pos"])
                state["pos"] = pos

        yield update


def echo_json(d: dict) -> None:
    """A command's figures as JSON on stdout (``--json``)."""
    import json

    from kukaid.jsonfile import jsonable

    click.echo(json.dumps(jsonable(d), indent=2))


JSON_HELP = "Print what was written and its figures as JSON on stdout."


@contextmanager
def usage_errors(option: str | None = None, types: tuple[type[KukaidError], ...] = (KukaidError,)) -> Iterator[None]:
    """Errors the library finds in values that come from options alone are usage errors (exit 2):
    ``with usage_errors("--noise"): ...`` around the code that checks them, never around reading a
    file (errors found in data files stay exit 1).  ``types``: only these errors."""
    try:
        yield
    except types as e:
        msg, ctx = str(e), click.get_current_context(silent=True)
        # the usage error names the command ('simulate', or 'fleet simulate' without the program's name)
        for name in ((ctx.command_path.partition(" ")[2], ctx.info_name) if ctx is not None else ()):
            if name and msg.startswith(f"{name}: "):
                msg = msg[len(name) + 2:]
                break
        if option is not None:
            raise click.BadParameter(msg, param_hint=option) from None
        raise click.UsageError(msg) from None


@contextmanager
def option_in_data_error(*options: tuple[str, bool, str]) -> Iterator[None]:
    """Options whose allowed range depends on the data (a cut-off below a log's Nyquist frequency,
    edge samples fewer than half the log) are checked with the data; the library's error names each
    as ``phrase``.  When one of them was given, the error is a usage error (exit 2) saying its flag:
    ``with option_in_data_error(("--cutoff", cutoff is not None, "filter cut-off"))``; an error of
    the defaults stays a data error (exit 1)."""
    from kukaid.errors import OptionError

    try:
        yield
    except KukaidError as e:
        msg = str(e)
        for flag, typed, phrase in options:
            if typed and phrase in msg:
                msg = msg.replace(phrase, flag, 1)
        if msg == str(e):
            raise
        raise OptionError(msg) from None


#: exit status of a command that completed with warnings under --strict (validate, run-admittance)
EXIT_WARNED = 4


def strict_exit(command: str, warnings: list[str], done: str = "completed") -> None:
    """``--strict``: exit with :data:`EXIT_WARNED` when there were ``warnings`` (after the output)."""
    if warnings:
        click.echo(f"kukaid: error: {command}: {done} with {len(warnings)} warning(s) (--strict)", err=True)
        raise SystemExit(EXIT_WARNED)


def require_positive(*options: tuple[str, float | None], zero_ok: bool = False) -> None:
    """Usage error unless every option given as ``(flag, value)`` is a finite number > 0 (``zero_ok``:
    >= 0; None: not given)."""
    for flag, v in options:
        if v is not None and not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0)):
            raise click.BadParameter(f"{v} must be a finite number {'>=' if zero_ok else '>'} 0", param_hint=flag)


def check_noise(noise: float | None) -> None:
    """``--noise`` of the one-axis virtual KR C4: a torque noise sigma within the simulator's range (N·m)."""
    from kukaid.sim.config import FIELDS

    lo, hi = FIELDS["noise_sigma"][1:3]
    if noise is not None and not lo <= noise <= hi:
        raise click.BadParameter(f"{noise} N·m is not a torque noise sigma of the simulator ({lo:g} to {hi:g} N·m)",
                                 param_hint="--noise")


def refuse_overwrite(path: Path, force: bool) -> None:
    """Recorded data is never lost: refuse to replace an existing log unless --force."""
    if path.exists() and not force:
        raise KukaidError(f"{path}: already exists; choose another name or pass --force to replace it")


def refuse_other_kind(path: Path | None, force: bool, *schemas: str) -> None:
    """A JSON output may replace a file of its own kind (its ``schema`` one of ``schemas``: a
    trajectory or fitted parameters, derived again from the options or logs), anything else only
    with --force (a parameter file is not lost to a trajectory written under its name)."""
    import json

    if path is None or force or not path.is_file():
        return
    try:
        kind = json.loads(path.read_text()).get("schema")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        kind = None
    if kind not in schemas:
        what = f"a {kind} file" if isinstance(kind, str) else "not a kukaid JSON file"
        raise KukaidError(f"{path}: already exists and is {what}, not {' or '.join(schemas)}; choose another "
                          "name or pass --force to replace it")


def check_outputs(outputs: Iterable[Path | None], inputs: Iterable[Path | None] = ()) -> None:
    """Before any work: every output can be a plain file, no two outputs are the same file, and
    no output is one of the inputs (a command never writes over what it reads)."""
    from kukaid.atomic import check_output

    outs = [Path(o) for o in outputs if o is not None]
    for k, o in enumerate(outs):
        check_output(o)
        if any(_same(o, x) for x in outs[:k]):
            raise KukaidError(f"{o}: the same file is given for two outputs")
    for i in (Path(i) for i in inputs if i is not None):
        for o in outs:
            if _same(o, i):
                raise KukaidError(f"{o}: is also an input of this command; write the output elsewhere")


def config_axis(sim_config: Path | None, axis: int | None, what: str, fix: str = "make the two agree") -> int | None:
    """The axis a --sim-config names ("axis"; None when it names none), checked against ``axis``, the one
    ``what`` moves (a trajectory's, --axis): a config of another axis is refused, never dropped in silence
    (the simulator runs one axis); ``fix`` (``{said}``: the file's axis) says how to mend it."""
    if sim_config is None:
        return None
    from kukaid.errors import SimConfigError
    from kukaid.jsonfile import read_json

    said = read_json(sim_config, SimConfigError)
    said = said.get("axis") if isinstance(said, dict) else None
    if said is not None and axis is not None and int(said) != int(axis):
        if int(said) > 6:  # an external axis: nothing to excite or guide on the virtual KR C4
            raise SimConfigError(f"{sim_config}: \"axis\": {said} is the external axis E{int(said) - 6}, which the "
                                 "virtual KR C4 does not simulate (its axes are 1 to 6; a real controller drives it: "
                                 f"--backend kvp); leave \"axis\" out: {what} moves A{axis}")
        raise SimConfigError(f"{sim_config}: \"axis\": {said}, but {what} moves A{axis}: the virtual KR C4 simulates "
                             f"one axis; leave \"axis\" out, or {fix.format(said=said)}")
    return None if said is None else int(said)


def check_suffix(path: Path | None, *suffixes: str) -> None:
    """Refuse an output whose name does not say its format (``.json``, ``.pdf``, ``.h5`` ...)."""
    if path is not None and path.suffix.lower() not in suffixes:
        raise click.UsageError(f"{path}: this output is {' or '.join(suffixes)}; name it so")


def _same(a: Path, b: Path) -> bool:
    import os

    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist yet
        return a.resolve() == b.resolve()


def krl_texts(outdir: Path, files: dict[str, str], force: bool) -> dict[Path, str]:
    """KRL files (name -> text) as path -> text with the controller's CR LF line ends; existing
    files only with --force (they may have been edited for the robot)."""
    for name in files:
        refuse_overwrite(outdir / name, force)
    return {outdir / name: text.replace("\n", "\r\n") for name, text in files.items()}


def write_krl_files(outdir: Path, files: dict[str, str], force: bool) -> None:
    """Write KRL files (name -> text) into ``outdir`` all or none (:func:`krl_texts`)."""
    from kukaid.atomic import write_texts_atomic

    write_texts_atomic(krl_texts(outdir, files, force))
