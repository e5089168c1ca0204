"""Command line: `trunk-drake <command> ...` (see `trunk-drake --help`).

The commands are the modules of `trunk_drake.commands` (one module per command). What every
command shares lives here: `--out` checked and created before the work starts, bad input and a
diverging simulation as one error line, warnings as one plain line, and Ctrl-C as one line
naming the partial results.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings
from pathlib import Path

from trunk_drake.commands import command_modules, plain_warning
from trunk_drake.parallel import caused_by_interrupt, noting_interrupts

INTERRUPTED = 130  # exit status of a command stopped by SIGINT (128 + 2)


class Parser(argparse.ArgumentParser):
    """argparse with one error line (what, and where to read more) instead of usage + error."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from trunk_drake.metadata import package_versions

    parser = Parser(prog="trunk-drake", description="Neuromusculoskeletal lumbar-spine simulation on Drake.")
    versions = package_versions()
    parser.add_argument("--version", action="version",
                        version=f"trunk-drake {versions.pop('trunk-drake')} ({', '.join(f'{k} {v}' for k, v in versions.items())})")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in command_modules():
        module.add_command(sub)
    for command in _leaf_parsers(sub):
        command.add_argument("--model", default=None, metavar="PATH",
                             help="an OpenSim .osim model to use instead of the embedded MyoTorso (every model this run loads)")
    return parser


def _leaf_parsers(sub):
    for parser in sub.choices.values():
        group = parser.get_default("group_commands")
        yield from (_leaf_parsers(group) if group is not None else (parser,))


def prepare_out(out) -> Path:
    """The output folder, created now (before the work) so that a bad --out fails at once."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {out} is a file, not a folder: give a folder (it is created if missing)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"--out {out}: cannot create the folder ({err.strerror}): give a writable folder") from None
    if not os.access(path, os.W_OK):
        raise ValueError(f"--out {out} is not writable: give a writable folder")
    return path


def _files(folder: Path | None) -> dict:
    if folder is None or not folder.is_dir():
        return {}
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


def interrupted_message(out: Path | None, before: dict, resumable: bool) -> str:
    """One line: interrupted, and where the partial results are (if the run wrote any)."""
    if _files(out) == before or not _files(out):
        return "interrupted"
    return f"interrupted; partial results in {out}" + ("; rerun the same command to resume" if resumable else "")


def _quiet_interrupts(unraisable, report=sys.unraisablehook) -> None:
    """sys.unraisablehook: a Ctrl-C caught inside native code (numba, a Drake callback), bare or
    re-wrapped by it, is no traceback for the user; main() reports the interruption."""
    if not caused_by_interrupt(unraisable.exc_value):
        report(unraisable)


def main(argv: list[str] | None = None) -> int:
    run = {"out": None, "before": {}, "resumable": False}
    hook, sys.unraisablehook = sys.unraisablehook, _quiet_interrupts
    with warnings.catch_warnings(), noting_interrupts() as listening:
        warnings.showwarning = plain_warning
        try:
            return _run(argv, run)
        except BaseException as error:
            if not caused_by_interrupt(error):
                raise
            if listening:
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C while the message is written
            print(interrupted_message(run["out"], run["before"], run["resumable"]), file=sys.stderr)
            if argv is None:  # the command line: skip the interpreter's teardown (1-2 s with Drake loaded);
                sys.stdout.flush()  # the work is abandoned and its files are closed already
                sys.stderr.flush()
                os._exit(INTERRUPTED)
            return INTERRUPTED
        finally:
            sys.unraisablehook = hook


def _run(argv, run: dict) -> int:
    from trunk_drake.model.trunk_model import model_source
    from trunk_drake.simulation import SimulationError

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as stop:  # --help, --version, or a usage error (already printed)
        return int(stop.code or 0)
    run["resumable"] = getattr(args, "resumable", False)
    try:
        if getattr(args, "out", None) is not None:
            run["out"] = prepare_out(args.out)
            run["before"] = _files(run["out"])
        with model_source(args.model):
            return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError, SimulationError) as err:
        if caused_by_interrupt(err):  # a Ctrl-C that native code turned into another error
            raise
        print(f"trunk-drake: error: {err}", file=sys.stderr)
        return 1 if isinstance(err, SimulationError) else 2


if __name__ == "__main__":
    sys.exit(main())
