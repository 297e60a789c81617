"""The ``kukaid`` command.  Subcommands are the modules ``cli/cmd_<name>.py`` (each defines
``command``), found without importing them, so ``kukaid --help`` and ``--version`` stay fast:
heavy libraries are imported inside the commands."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from kukaid import __version__

_HERE = Path(__file__).parent


def _command_names() -> list[str]:
    return sorted(p.stem[4:].replace("_", "-") for p in _HERE.glob("cmd_*.py"))


class LazyGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return _command_names()

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in _command_names():
            return None
        import importlib

        mod = importlib.import_module(f"{__package__}.cmd_{name.replace('-', '_')}")
        return mod.command

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """Click's main, with its usage errors (a missing option, a value out of range, a folder
        where a file belongs) as one line, ``kukaid: error: <command>: <what>``, exit status 2."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, False, **extra)
        except click.exceptions.NoArgsIsHelpError as e:  # `kukaid` or `kukaid CMD` alone: the help, as --help
            click.echo(e.ctx.get_help())
            sys.exit(0)
        except click.ClickException as e:
            ctx = getattr(e, "ctx", None)
            # the command as typed after `kukaid` (`fleet fit`, not `fit`, which is another command)
            where = " ".join(ctx.command_path.split()[1:]) + ": " if ctx is not None and ctx.parent is not None else ""
            _fail(where + " ".join(e.format_message().split()), e.exit_code)
        except click.Abort:
            _fail("interrupted", 130)
        sys.exit(rv if isinstance(rv, int) else 0)

    def invoke(self, ctx: click.Context):
        from kukaid.errors import EXIT_INTERNAL, KukaidError

        try:
            return super().invoke(ctx)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except KukaidError as e:
            _fail(str(e), e.exit_code)
        except KeyboardInterrupt:
            _fail("interrupted", 130)
        except BrokenPipeError as e:
            if not _stdout_gone():
                _fail(f"{e.strerror or e}", 1)
            _quiet_exit()
        except OSError as e:
            where = f"{e.filename}: " if getattr(e, "filename", None) else ""
            _fail(f"{where}{e.strerror or e}", 1)
        except Exception as e:  # a bug: still one line, full traceback with KUKAID_DEBUG=1
            if os.environ.get("KUKAID_DEBUG"):
                raise
            _fail(f"internal error ({type(e).__name__}: {e}); rerun with KUKAID_DEBUG=1 for a traceback",
                  EXIT_INTERNAL)


#: exit status when stdout's reader has gone (`kukaid ... | head`): 128 + SIGPIPE, as a command
#: killed by the signal; no message (the reader asked for no more)
EXIT_BROKEN_PIPE = 141


def _stdout_gone() -> bool:
    """True when stdout is a pipe whose reader has closed it (POLLERR on its write end)."""
    import select

    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no descriptor (tests) or no poll: the pipe was stdout
        return True


def _quiet_exit() -> None:
    """Stop without a word on a broken stdout: what the command wrote to files stays (outputs are
    complete before the summary is printed); stdout goes to /dev/null so the interpreter's final
    flush does not complain."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (AttributeError, OSError, ValueError):
        pass
    sys.exit(EXIT_BROKEN_PIPE)


def _fail(msg: str, code: int) -> None:
    click.echo(f"kukaid: error: {msg}", err=True)
    sys.exit(code)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="kukaid")
def cli() -> None:
    """Identify a KUKA robot axis (Yao et al. 2018) and push it by hand without a force sensor.

    Pipeline: excite -> capture (or load) -> fit -> report / diagnose -> run-admittance.
    Every command that needs a robot uses the built-in virtual KR C4 unless told otherwise.
    """


def main() -> None:
    cli(prog_name="kukaid")


if __name__ == "__main__":
    main()
