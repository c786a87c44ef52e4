"""The ``phyloc`` command line.

Commands:

* ``phyloc bench [phy|channels|ranging|dipnet|datasets|pfbp|nbp|control|analysis|memory|
  memory_large|sionna|all] [--quick] [--json PATH]``: run benchmarks; print cost per unit of
  work and ratios to references.
* ``phyloc evaluate RECIPE|OUT.h5 [--fast] [--out DIR] [--json PATH]
  [--workers N | --scheduler ADDR] [--resume] [--plugin MODULE]``: run an experiment recipe,
  or localize on a dataset's waveforms (``--resume`` finishes an interrupted run); write
  ``results.json``, the recipe and a PNG into DIR.
  ``--plugin`` imports a module (name or ``.py`` path) that registers the user's own
  localization methods.
* ``phyloc generate RECIPE -o OUT.h5 [--workers N | --scheduler ADDR] [--resume]``: generate an
  HDF5 waveform dataset (sharded, resumable).
* ``phyloc info OUT.h5 [--verify] [--json PATH]``: summarize a dataset; with ``--verify`` check
  every checksum.
* ``phyloc import ARRAYS.npz|ARRAYS.h5 -o OUT.h5 [--recipe R.toml] [--force]``: write recorded
  OFDM snapshots (raw arrays, see ``datasets/README.md``) into a dataset.
* ``phyloc export OUT.h5 -o ARRAYS.npz|ARRAYS.h5 [--force]``: write a dataset's waveforms and
  truth as the raw arrays ``phyloc import`` reads.
* ``phyloc quickstart [--dir DIR]``: generate the small urban quickstart dataset and compare
  DiPNet with two-step methods.
* ``phyloc channel-stats SCENARIO [--square SIDE_M] [--links N] [--seed S] [--png PATH]
  [--json PATH]``: draw links of a channel scenario and compare realized statistics with its
  table.
* ``phyloc channel-compare SCENARIO... [--links N] [--carrier-frequency-hz F] [--seed S]
  [--png PATH] [--json PATH] [--force]``: draw TR 38.901 scenarios in phyloc and in NVIDIA Sionna
  (optional dependency) and compare their statistics.
* ``phyloc analyze cci SCENARIO... | belief-shift [--json PATH]``: DiPNet Figs. 2 and 3 from
  flags (presets: they build a ``cci`` / ``belief_shift`` recipe and run that experiment).

The parser is built from the table :data:`COMMANDS`; the handlers are in
:mod:`phyloc.commands`.
Errors a user can cause are printed as one line without a traceback (exit status 2).

References
----------
DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.

PF-BP: L. Wielandner, E. Leitinger, F. Meyer and K. Witrisal, "Message passing-based 9-D
cooperative localization and navigation with embedded particle flow."

POA-NBP: R. Mendrzik and G. Bauch, "Position-constrained stochastic inference for cooperative
indoor localization."
"""

from __future__ import annotations

import argparse
import sys

from phyloc import commands
from phyloc.commands import BENCHMARKS
from phyloc.errors import PhylocError


def _arg(*flags, **kw):
    """One ``add_argument`` call, as data."""
    return flags, kw


#: Shared options.
WORKERS = _arg(
    "--workers",
    type=int,
    default=None,
    metavar="N",
    help="run tasks on a local Dask cluster of N processes (default: in-process)",
)
SCHEDULER = _arg(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="run tasks on an existing Dask scheduler (tcp://host:port)",
)
NO_PROGRESS = _arg("--no-progress", action="store_true", help="no progress bar")
JSON = _arg("--json", metavar="PATH", help="also write the figures as JSON to PATH")
SEED = _arg("--seed", type=int, default=0, help="random seed (default 0)")


def _force(what: str = "--json file"):
    return _arg("--force", action="store_true", help=f"replace an existing {what}")


def _png(default: str):
    return _arg("--png", metavar="PATH", default=None, help=f"figure (default {default})")


def _output(help_: str, metavar: str = "OUT.h5"):
    return _arg("-o", "--output", required=True, metavar=metavar, help=help_)


#: ``(name, help, handler, [arguments])`` of every command; ``analyze`` has sub-commands.
COMMANDS = [
    (
        "bench",
        "run benchmarks and print their cost per unit of work",
        "cmd_bench",
        [
            _arg(
                "suite",
                nargs="?",
                default="phy",
                choices=[*BENCHMARKS, "all"],
                help="which benchmark suite (default: phy)",
            ),
            _arg("--quick", action="store_true", help="shorter runs (less precise)"),
            JSON,
            _force(),
        ],
    ),
    (
        "claims",
        "the papers' claims with the verdicts their stored runs give at 95 %%",
        "cmd_claims",
        [
            _arg(
                "--ledger",
                default="docs/claims.toml",
                metavar="PATH",
                help="the claims ledger (default docs/claims.toml, from the repository root)",
            ),
            _arg(
                "--results",
                default="docs/results",
                metavar="DIR",
                help="the stored runs (default docs/results)",
            ),
            _arg("--paper", default=None, metavar="NAME", help="only this paper's claims"),
            JSON,
            _force(),
        ],
    ),
    (
        "generate",
        "generate an HDF5 waveform dataset from a recipe",
        "cmd_generate",
        [
            _arg(
                "recipe", help='dataset recipe (kind = "dataset", e.g. datasets/quickstart_c2.toml)'
            ),
            _output("master HDF5 file"),
            WORKERS,
            SCHEDULER,
            _arg(
                "--resume",
                action="store_true",
                help="complete an interrupted run: redo only missing or corrupt shards",
            ),
            NO_PROGRESS,
            _arg("--json", metavar="PATH", help="also write the summary as JSON"),
            _force(),
        ],
    ),
    (
        "info",
        "summarize a dataset (and verify its checksums)",
        "cmd_info",
        [
            _arg("dataset", help="master HDF5 file written by phyloc generate"),
            _arg("--verify", action="store_true", help="check every shard's checksums"),
            JSON,
            _force(),
        ],
    ),
    (
        "import",
        "write recorded OFDM snapshots (raw arrays) into a phyloc dataset",
        "cmd_import",
        [
            _arg(
                "source",
                help="an .npz file or a plain HDF5 file of the arrays named in datasets/README.md",
            ),
            _output("master HDF5 file"),
            _arg(
                "--recipe",
                default=None,
                metavar="R.toml",
                help="seed, name, [channel] scenario label, [ranging], [localization] and "
                "[experiment] for phyloc evaluate (default: the source's recipe text, else "
                "defaults)",
            ),
            _force("output and its shard folder"),
        ],
    ),
    (
        "export",
        "write a dataset's waveforms and truth as the raw arrays import reads",
        "cmd_export",
        [
            _arg("dataset", help="master HDF5 file of a dataset"),
            _output(".npz, .h5 or .hdf5 file", "ARRAYS.npz"),
            _force("output"),
        ],
    ),
    (
        "quickstart",
        "generate a small C2 dataset and compare DiPNet with two-step localization "
        "on it (about 15 s on 2 cores; a first run also compiles the kernels, about 30 s)",
        "cmd_quickstart",
        [
            _arg(
                "--dir",
                default="quickstart",
                metavar="DIR",
                help="where the dataset and a new results folder go (default ./quickstart)",
            ),
            _arg(
                "--workers",
                type=int,
                default=2,
                metavar="N",
                help="Dask worker processes for generation and evaluation (default 2)",
            ),
            NO_PROGRESS,
        ],
    ),
    (
        "evaluate",
        "run an experiment recipe or evaluate a dataset",
        "cmd_evaluate",
        [
            _arg("recipe", help="a recipe TOML file (datasets/*.toml) or a dataset (.h5)"),
            _arg(
                "--fast",
                action="store_true",
                help="the recipe's [experiment.fast] setting (small, for CI)",
            ),
            _arg(
                "--out",
                metavar="DIR",
                default=None,
                help="results folder (default results/<recipe name>[-fast])",
            ),
            WORKERS,
            SCHEDULER,
            NO_PROGRESS,
            _arg(
                "--resume",
                action="store_true",
                help="finish an interrupted run in --out: the tasks it finished (kept in "
                "OUT/.tasks) are read back, the others run",
            ),
            _arg(
                "--no-verify",
                action="store_true",
                help="evaluating a dataset: skip the SHA-256 check of its shard files before "
                "reading",
            ),
            _arg(
                "--plugin",
                action="append",
                default=[],
                metavar="MODULE",
                help="import MODULE (a module name or a .py file) that registers localization "
                "methods with phyloc.localization.register_method; repeatable",
            ),
            JSON,
            _force("--json file or a non-empty --out folder"),
        ],
    ),
    (
        "channel-stats",
        "draw links of a channel scenario and compare their statistics with its table",
        "cmd_channel_stats",
        [
            _arg("scenario", help="scenario name (e.g. winner2_c2) or a path to a TOML file"),
            _arg(
                "--square",
                type=float,
                default=100.0,
                metavar="SIDE_M",
                help="side of the square the link end points are drawn in [m] (default 100)",
            ),
            _arg(
                "--links",
                type=int,
                default=20000,
                metavar="N",
                help="number of links to draw (default 20000)",
            ),
            SEED,
            _png("channel_stats_<scenario>.png: example power-delay profiles"),
            JSON,
            _force("--json/--png file"),
        ],
    ),
    (
        "channel-compare",
        "draw TR 38.901 scenarios in phyloc and in NVIDIA Sionna (pip install sionna) and "
        "compare their statistics",
        "cmd_channel_compare",
        [
            _arg(
                "scenarios",
                nargs="+",
                metavar="SCENARIO",
                help="tr38901_umi, tr38901_uma, tr38901_rma, tr38901_inh_mixed, tr38901_inh_open, "
                "tr38901_inf_sl, _dl, _sh, _dh, tdl_a ... tdl_e, or all",
            ),
            _arg(
                "--links",
                type=int,
                default=4000,
                metavar="N",
                help="links per draw and LOS state (default 4000)",
            ),
            _arg(
                "--carrier-frequency-hz",
                type=float,
                default=3.5e9,
                metavar="F",
                help="carrier frequency [Hz] of both packages (default 3.5e9)",
            ),
            SEED,
            _png("channel_compare_<scenarios>.png"),
            JSON,
            _force("--json/--png file"),
        ],
    ),
]

ANALYSES = [
    (
        "belief-shift",
        "belief shift under a distance offset: DiPNet vs two-step (DiPNet Fig. 3)",
        "cmd_belief_shift",
        [
            _arg(
                "--nu", type=float, default=1.0, help="ν = CRB/σ0², measurement/prior (default 1)"
            ),
            _arg("--subcarriers", type=int, default=2569, metavar="N", help="N (default 2569)"),
            _png("belief_shift_nu<ν>.png"),
            JSON,
            _force("--json/--png file"),
        ],
    ),
    (
        "cci",
        "conditional concavity indicator of channel scenarios (DiPNet Fig. 2)",
        "cmd_cci",
        [
            _arg(
                "scenarios",
                nargs="+",
                metavar="SCENARIO",
                help="scenario names (winner2_c2, exponential, ...) or scenario TOML files",
            ),
            _arg(
                "--bandwidth-hz",
                type=float,
                default=None,
                metavar="B",
                help="bandwidth B = N f_sc [Hz] (default 37.6 MHz, DiPNet §V-A)",
            ),
            _arg(
                "--subcarriers", type=int, default=2569, metavar="N", help="N, odd (default 2569)"
            ),
            _arg(
                "--carrier-hz",
                type=float,
                default=5.2e9,
                metavar="FC",
                help="carrier frequency of the path-loss laws [Hz] (default 5.2e9)",
            ),
            _arg(
                "--distance-m",
                type=float,
                default=10.0,
                metavar="D",
                help="distance of the reported minimal bandwidth of DiPNet eq. (44) [m] "
                "(default 10)",
            ),
            _arg(
                "--links",
                type=int,
                default=20000,
                metavar="N",
                help="Monte Carlo links per distance, 0 for none (default 20000)",
            ),
            _arg(
                "--mc-points",
                type=int,
                default=21,
                metavar="K",
                help="Monte Carlo distances (default 21)",
            ),
            SEED,
            NO_PROGRESS,
            _png("cci_<scenarios>.png"),
            JSON,
            _force("--json/--png file"),
        ],
    ),
]


def _add_commands(sub, table) -> None:
    """One sub-parser per row of ``table`` (:data:`COMMANDS`, :data:`ANALYSES`)."""
    for name, help_, handler, arguments in table:
        p = sub.add_parser(name, help=help_)
        for flags, kw in arguments:
            p.add_argument(*flags, **kw)
        p.set_defaults(func=getattr(commands, handler))


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``phyloc`` command (built from :data:`COMMANDS`)."""
    from phyloc import __version__

    parser = argparse.ArgumentParser(
        prog="phyloc",
        description="Signal-level PHY simulation and direct localization of wireless networks.",
    )
    parser.add_argument("--version", action="version", version=f"phyloc {__version__}")
    parser.add_argument(
        "--debug",
        action="store_true",
        help="show the full traceback of an error instead of one line",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_commands(sub, COMMANDS)
    analyze = sub.add_parser("analyze", help="analyses from the theory (DiPNet §IV)")
    asub = analyze.add_subparsers(dest="analysis", metavar="ANALYSIS")
    asub.required = True
    _add_commands(asub, ANALYSES)
    return parser


def redeliver_lost_interrupts(unraisable) -> None:
    """``sys.unraisablehook`` that does not lose Ctrl-C: a KeyboardInterrupt raised while Python
    ran a finalizer or weakref callback is only printed ("Exception ignored in …") and the
    command would go on; it is raised again in the main thread instead (after 50 ms, outside
    the callback). Everything else goes to Python's own hook."""
    if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        import _thread
        import threading

        threading.Timer(0.05, _thread.interrupt_main).start()
        return
    sys.__unraisablehook__(unraisable)


def main(argv=None) -> int:
    """Entry point of the console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.parse_args = parser.parse_args  # a command that runs others (quickstart) parses theirs
    previous_hook, sys.unraisablehook = sys.unraisablehook, redeliver_lost_interrupts
    try:
        return _run(args)
    finally:
        sys.unraisablehook = previous_hook


def _run(args) -> int:
    """Run the parsed command; every error a user can cause is one line and an exit status."""
    try:
        return int(args.func(args) or 0)
    except PhylocError as exc:
        if args.debug:
            raise
        print(f"phyloc: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # permission denied, disk full, a file where a folder should be, …
        if args.debug:
            raise
        print(f"phyloc: error: {_os_error(exc, getattr(args, 'func', None))}", file=sys.stderr)
        return 2
    except Exception as exc:  # a defect of phyloc: one line, the traceback on request
        if args.debug:
            raise
        print(
            f"phyloc: internal error: {type(exc).__name__}: {exc} "
            "(run with --debug for the traceback)",
            file=sys.stderr,
        )
        return 1
    except KeyboardInterrupt:
        hint = ""
        if getattr(args, "func", None) is commands.cmd_generate:
            hint = "; finished shards are kept: run the same command with --resume to finish it"
        if getattr(args, "func", None) is commands.cmd_evaluate:
            hint = "; finished tasks are kept: run the same command with --resume to finish it"
        print(f"phyloc: interrupted{hint}", file=sys.stderr)
        return 130


def _os_error(exc: OSError, func=None) -> str:
    """One line for an operating-system error: what failed, on which path, and the likely
    remedy for the common cases (for a full disk: what the command ``func`` kept)."""
    import errno

    where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
    what = exc.strerror or str(exc).splitlines()[0] or type(exc).__name__
    full = "the disk is full; free space or choose another path"
    if func is commands.cmd_generate:
        full = "the disk is full; completed shards are kept: free space and rerun with --resume"
    elif func is commands.cmd_evaluate:
        full = "the disk is full; finished tasks are kept: free space and rerun with --resume"
    hint = {
        errno.EACCES: "check the permissions or choose another path",
        errno.EROFS: "the file system is read-only; choose another path",
        errno.ENOSPC: full,
        errno.EISDIR: "a folder is in the way; give a file path",
        errno.ENOTDIR: "a file is in the way where a folder is needed; choose another path",
    }.get(exc.errno)
    return f"{what}{where}" + (f" ({hint})" if hint else "")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
