"""The ``phyloc`` command line.

Commands:

* ``phyloc bench [phy|channels|ranging|dipnet|datasets|pfbp|nbp|control|analysis|memory|sionna|all]
  [--quick] [--json PATH]``: run benchmarks; print cost per unit of work and ratios to references.
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
import hashlib
import importlib
import shutil
import sys
import time
from datetime import UTC

from phyloc.errors import PhylocError, ValidationError

BENCHMARKS = {
    "phy": "phyloc.benchmarks.bench_phy",
    "channels": "phyloc.benchmarks.bench_channels",
    "ranging": "phyloc.benchmarks.bench_ranging",
    "dipnet": "phyloc.benchmarks.bench_dipnet",
    "datasets": "phyloc.benchmarks.bench_datasets",
    "pfbp": "phyloc.benchmarks.bench_pfbp",
    "nbp": "phyloc.benchmarks.bench_nbp",
    "control": "phyloc.benchmarks.bench_control",
    "analysis": "phyloc.benchmarks.bench_analysis",
    "memory": "phyloc.benchmarks.bench_memory",
    "sionna": "phyloc.benchmarks.bench_sionna",
}


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
        "on it (about a minute on 2 cores once the kernels are compiled)",
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


def _add_commands(sub, commands) -> None:
    for name, help_, handler, arguments in commands:
        p = sub.add_parser(name, help=help_)
        for flags, kw in arguments:
            p.add_argument(*flags, **kw)
        p.set_defaults(func=globals()[handler])


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


def main(argv=None) -> int:
    """Entry point of the console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
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
        print(f"phyloc: error: {_os_error(exc)}", file=sys.stderr)
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
        if getattr(args, "func", None) is cmd_generate:
            hint = "; finished shards are kept: run the same command with --resume to finish it"
        if getattr(args, "func", None) is cmd_evaluate:
            hint = "; finished tasks are kept: run the same command with --resume to finish it"
        print(f"phyloc: interrupted{hint}", file=sys.stderr)
        return 130


def _os_error(exc: OSError) -> str:
    """One line for an operating-system error: what failed, on which path, and the likely
    remedy for the common cases."""
    import errno

    where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
    what = exc.strerror or str(exc).splitlines()[0] or type(exc).__name__
    hint = {
        errno.EACCES: "check the permissions or choose another path",
        errno.EROFS: "the file system is read-only; choose another path",
        errno.ENOSPC: "the disk is full; free space (completed shards are kept: --resume)",
        errno.EISDIR: "a folder is in the way; give a file path",
        errno.ENOTDIR: "a file is in the way where a folder is needed; choose another path",
    }.get(exc.errno)
    return f"{what}{where}" + (f" ({hint})" if hint else "")


# -- bench -----------------------------------------------------------------------------------
def cmd_bench(args) -> int:
    """``phyloc bench``: run the suites, print their tables, optionally write JSON."""
    _check_outputs(args)  # fail before spending a minute on the benchmark
    suites = list(BENCHMARKS) if args.suite == "all" else [args.suite]
    figures: dict[str, float] = {}
    t0 = time.perf_counter()
    for name in suites:
        mod = _import_benchmark(BENCHMARKS[name])
        print(f"== phyloc bench {name}{' (quick)' if args.quick else ''} ==", flush=True)
        fig = mod.report(quick=args.quick)
        summarize = getattr(mod, "summarize", None)
        print(summarize(fig) if summarize else _generic_table(fig))
        print()
        figures.update(fig)
    meta = {
        "command": "bench",
        "suite": args.suite,
        "quick": bool(args.quick),
        "seconds": time.perf_counter() - t0,
    }
    _write_json(args, figures, meta)
    return 0


def _import_benchmark(module: str):
    """Import a benchmark module from the installed package or, in a source checkout where
    ``phyloc`` is imported from the working tree, from the top-level ``benchmarks`` folder."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name not in ("phyloc.benchmarks", module):
            raise
        return importlib.import_module(module.replace("phyloc.benchmarks.", "benchmarks."))


def _generic_table(fig: dict) -> str:
    from phyloc.reporting import format_table

    return format_table([(k, v) for k, v in fig.items()], ["figure", "value"])


# -- evaluate --------------------------------------------------------------------------------


def cmd_evaluate(args) -> int:
    """``phyloc evaluate``: run a recipe, print its table, write the results folder."""
    from pathlib import Path

    from phyloc.evaluation.kinds import (
        DATASET_LOCALIZATION,
        experiment_for,
        load_recipe,
        validate_recipe,
    )
    from phyloc.parallel import TaskStore, TaskStoreBusy, TaskStoreMismatch, task_store
    from phyloc.reporting import OutputExistsError, format_table, machine_meta, write_json

    if args.plugin:
        from phyloc.localization.registry import add_plugins

        add_plugins(args.plugin)
    source = Path(args.recipe)
    if source.suffix in (".h5", ".hdf5") or _is_hdf5(source):
        exp = DATASET_LOCALIZATION
        name = source.stem
        recipe = None
    else:
        recipe = load_recipe(args.recipe)
        exp = experiment_for(recipe.kind)
        validate_recipe(recipe)  # the full and the fast setting, before any work
        name = recipe.name
    out = Path(args.out or Path("results") / (name + ("-fast" if args.fast else "")))
    if out.exists() and not out.is_dir():
        raise ValidationError("--out", str(out), "is a file; give a results folder")
    tasks_dir = out / ".tasks"
    if args.resume and args.force:
        raise ValidationError(
            "--resume", "with --force", "--resume finishes a run, --force starts it over"
        )
    if args.resume and (out / "results.json").exists() and not tasks_dir.exists():
        raise PhylocError(
            f"--resume: the run in {out} is complete (results.json, no unfinished tasks); "
            "pass --force to run it again"
        )
    if out.exists() and any(out.iterdir()) and not (args.force or args.resume):
        raise OutputExistsError(out)
    if args.json and Path(args.json).exists() and not args.force:
        raise OutputExistsError(args.json)
    if args.force and tasks_dir.exists():
        shutil.rmtree(tasks_dir)
    t0 = time.perf_counter()
    kw = {
        "fast": args.fast,
        "workers": args.workers,
        "scheduler": args.scheduler,
        "progress": not args.no_progress,
    }
    verify_s = None
    if recipe is None and not args.no_verify:  # never compute on corrupt waveforms
        from phyloc.datasets.integrity import check_shard_files

        checked = check_shard_files(source)
        verify_s = checked["seconds"]
        print(
            f"checked {checked['shards']} shard checksums ({checked['bytes'] / 1e6:.1f} MB) "
            f"in {verify_s:.2f} s (--no-verify skips this)"
        )
    text = recipe.text if recipe is not None else _dataset_recipe_text(source)
    identity = {
        "recipe_sha256": hashlib.sha256(text.encode()).hexdigest(),
        "source": source.name,
        "fast": bool(args.fast),
    }
    out_existed = out.exists()
    try:
        store = TaskStore(tasks_dir, identity, resume=args.resume)
    except TaskStoreMismatch as exc:
        raise PhylocError(
            f"--resume: the unfinished run in {out} differs in {exc} (code: phyloc's sources "
            "changed since it started; recipe_sha256/source/fast: another recipe or setting); "
            "finish it with the code and recipe that started it, or start over with --force"
        ) from None
    except TaskStoreBusy as exc:
        raise PhylocError(
            f"another phyloc evaluate is running into {out} ({exc}); wait for it, or stop it "
            "and run this command again with --resume"
        ) from None
    try:
        with task_store(store):
            res = exp.run(recipe, **kw) if recipe is not None else exp.run_dataset(source, **kw)
    except BaseException:
        if store.invocations == 1 and store.computed == 0:  # nothing to resume: leave no trace
            shutil.rmtree(tasks_dir, ignore_errors=True)
            if not out_existed and not any(out.iterdir()):
                out.rmdir()
        raise
    wall = time.perf_counter() - t0
    if store.invocations > 1:
        print(
            f"resumed: {store.reused} finished tasks read back from {tasks_dir}, "
            f"{store.computed} run now (invocation {store.invocations})"
        )
    res["meta"].update({"seconds": wall, "machine": machine_meta(), "recipe_text": text})
    # every run records its wall time and worker count among its figures
    res["figures"]["run.wall_s"] = wall
    res["figures"]["run.workers"] = 0 if args.scheduler else int(args.workers or 1)
    if store.invocations > 1:  # a resumed run: its wall time over every invocation
        res["figures"]["run.wall_s"] = wall + store.wall_before
        res["figures"]["run.invocations"] = store.invocations
        res["figures"]["run.tasks_reused"] = store.reused
    if verify_s is not None:
        res["figures"]["run.verify_s"] = verify_s
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "results.json", res["figures"], res["meta"], res["series"], force=True)
    (out / "recipe.toml").write_text(text)
    png = out / f"{name}.png"
    exp.plot(res, png)
    print(f"{name}{' (fast)' if args.fast else ''}: {res['meta']['seconds']:.1f} s")
    print(format_table(exp.summary_rows(res), exp.summary_headers(res)))
    for line in exp.summary_lines(res):
        print(line)
    extra = sorted(p for p in out.glob(f"{name}_*.png"))  # further figures of the experiment
    print(f"wrote {', '.join(str(p) for p in [out / 'results.json', png, *extra])}")
    if args.json:
        write_json(args.json, res["figures"], res["meta"], res["series"], force=args.force)
        print(f"wrote {args.json}")
    shutil.rmtree(tasks_dir)  # the run is complete: its results are in results.json
    return 0


def _is_hdf5(path) -> bool:
    try:
        import h5py

        return path.is_file() and h5py.is_hdf5(path)
    except OSError:
        return False


def _dataset_recipe_text(path) -> str:
    from phyloc.datasets import open as open_dataset

    with open_dataset(path) as ds:
        return ds.recipe


# -- generate / info / quickstart --------------------------------------------------------------
def cmd_generate(args) -> int:
    """``phyloc generate``: write a sharded HDF5 dataset (see :func:`phyloc.datasets.generate`)."""

    from phyloc.datasets import generate
    from phyloc.evaluation.kinds import load_recipe, validate_recipe
    from phyloc.reporting import format_table

    _check_outputs(args)
    recipe = load_recipe(args.recipe)
    if recipe.kind != "dataset":
        raise ValidationError(
            "kind",
            recipe.kind,
            "phyloc generate takes a dataset recipe "
            '(kind = "dataset"); run experiment recipes with phyloc evaluate',
        )
    validate_recipe(recipe)  # incl. [experiment], [ranging], [localization]: before any work
    summary = generate(
        recipe,
        args.output,
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        progress=not args.no_progress,
    )
    rows = [(k, v) for k, v in summary.items() if isinstance(v, (int, float))]
    if not summary.get("bytes_written"):  # a resume that reused every shard: no bandwidth
        rows = [(k, v) for k, v in rows if k != "write_mb_per_s"]
    print(format_table(rows, ["generated " + str(summary.get("path", args.output)), ""]))
    meta = {"command": "generate", "recipe": recipe.name, "seed": recipe.seed}
    _write_json(args, dict(rows), meta)
    return 0


def cmd_info(args) -> int:
    """``phyloc info``: summary of a dataset; exit status 1 when ``--verify`` finds damage."""

    from phyloc.datasets import info
    from phyloc.reporting import format_table

    _check_outputs(args)
    res = info(args.dataset, verify=args.verify)
    flat = {}
    for k, v in res.items():
        if isinstance(v, dict):
            for k2, v2 in v.items():
                flat[f"{k}.{k2}"] = v2
        else:
            flat[k] = v
    rows = [
        (k, v if isinstance(v, (int, float, str)) or v is None else str(v)) for k, v in flat.items()
    ]
    print(format_table(rows, [str(args.dataset), ""]))
    figs = {
        k: v for k, v in flat.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
    }
    _write_json(args, figs, {"command": "info", "dataset": str(args.dataset), "info": flat})
    if args.verify and not res.get("ok", True):
        print(
            "phyloc: verify found a damaged master or missing or corrupt shards; repair with "
            "phyloc generate RECIPE -o FILE --resume",
            file=sys.stderr,
        )
        return 1
    return 0


def cmd_import(args) -> int:
    """``phyloc import``: raw arrays → dataset (see :func:`phyloc.datasets.import_arrays`)."""
    from phyloc.datasets import import_arrays, info

    out = import_arrays(args.source, args.output, recipe=args.recipe, force=args.force)
    s = info(out)
    print(
        f"imported {args.source}: {s['n_realizations']} realization(s) x {s['n_snapshots']} "
        f"snapshot(s), {s['n_agents']} agents + {s['n_anchors']} anchors, {s['links']} "
        f"link waveforms, N = {s['n_subcarriers']} -> {out}"
    )
    return 0


def cmd_export(args) -> int:
    """``phyloc export``: dataset → raw arrays (see :func:`phyloc.datasets.export_arrays`)."""
    from phyloc.datasets import export_arrays

    out = export_arrays(args.dataset, args.output, force=args.force)
    print(f"exported {args.dataset} -> {out}")
    return 0


def cmd_quickstart(args) -> int:
    """``phyloc quickstart``: the README's main job (generate, then evaluate, in DIR)."""
    from datetime import datetime
    from importlib.resources import files
    from pathlib import Path

    from phyloc.evaluation.kinds import load_recipe

    root = Path(args.dir)
    root.mkdir(parents=True, exist_ok=True)
    try:
        text = (files("phyloc.recipes") / "quickstart_c2.toml").read_text()
    except (ModuleNotFoundError, FileNotFoundError):
        text = None  # a source checkout imported from its working tree
    recipe_path = root / "quickstart_c2.toml"
    if not recipe_path.exists():
        recipe_path.write_text(text if text is not None else _quickstart_recipe_text())
    recipe = load_recipe(recipe_path)
    h5 = root / "quickstart_c2.h5"
    print(f"== 1/2 generate {h5} (resumes if it exists) ==", flush=True)
    common = ["--workers", str(args.workers)] if args.workers else []
    common += ["--no-progress"] if args.no_progress else []
    # the sub-commands' own parsers build their arguments, so no option can be missing
    gen = build_parser().parse_args(
        ["generate", str(recipe_path), "-o", str(h5), *common, *(["--resume"] * h5.exists())]
    )
    cmd_generate(gen)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    out = root / f"results-{stamp}"
    print(f"\n== 2/2 evaluate DiPNet and two-step methods on {h5} ==", flush=True)
    ev = build_parser().parse_args(["evaluate", str(h5), "--out", str(out), *common])
    del recipe
    return cmd_evaluate(ev)


def _quickstart_recipe_text() -> str:
    from pathlib import Path

    return (Path(__file__).resolve().parents[1] / "datasets" / "quickstart_c2.toml").read_text()


# -- channel-stats ---------------------------------------------------------------------------
def cmd_channel_stats(args) -> int:
    """``phyloc channel-stats``: realized statistics of a scenario versus its table."""
    from pathlib import Path

    import numpy as np

    from phyloc.channels.stats import channel_stats, plot_power_delay_profiles
    from phyloc.reporting import format_table

    png = Path(args.png or f"channel_stats_{Path(args.scenario).stem}.png")
    _check_outputs(args, png)
    rng = np.random.default_rng(args.seed)
    res = channel_stats(args.scenario, square_m=args.square, n_links=args.links, rng=rng)
    print(
        f"channel statistics of {args.scenario}: {args.links} links, "
        f"end points uniform in a {args.square:g} m square, seed {args.seed}"
    )
    print(format_table(res["table"], ["quantity", "realized", "table"]))
    plot_power_delay_profiles(res["draw"], png)
    print(f"wrote {png}")
    meta = {
        "command": "channel-stats",
        "scenario": args.scenario,
        "seed": args.seed,
        "links": args.links,
        "square_m": args.square,
    }
    _write_json(args, res["figures"], meta, res.get("series"))
    return 0


def _check_outputs(args, *paths) -> None:
    """Refuse, before any work, to overwrite ``--json`` or any of ``paths`` without
    ``--force``."""
    from pathlib import Path

    from phyloc.reporting import OutputExistsError

    for p in (getattr(args, "json", None), *paths):
        if p and Path(p).exists() and not args.force:
            raise OutputExistsError(p)


def _write_json(args, figures: dict, meta: dict, series=None) -> None:
    """``--json PATH`` (when given): the figures, ``meta`` with the machine, and ``series``."""
    from phyloc.reporting import machine_meta, write_json

    if args.json:
        meta = {**meta, "machine": machine_meta()}
        path = write_json(args.json, figures, meta, series, force=args.force)
        print(f"wrote {path}")


def _run_preset(args, doc: dict, flags: dict, png) -> int:
    """Run the recipe ``doc`` built from command-line flags (an ``analyze`` preset) through
    its experiment, exactly as ``phyloc evaluate`` would; errors name the flag a recipe key
    came from (``flags``: recipe key prefix -> flag)."""
    from phyloc.config import dumps_toml
    from phyloc.evaluation.kinds import experiment_for, load_recipe
    from phyloc.reporting import format_table

    _check_outputs(args, png)
    try:
        recipe = load_recipe("\n" + dumps_toml(doc))
        exp = experiment_for(recipe.kind)
        exp.prepare(recipe)
    except ValidationError as exc:
        key = next((k for k in flags if exc.field.startswith(k)), None)
        if key is None:
            raise
        value = getattr(args, flags[key]["arg"], exc.value) if "arg" in flags[key] else exc.value
        field = flags[key]["flag"] + exc.field[len(key) :]
        raise ValidationError(field, value, exc.allowed) from None
    res = exp.run(recipe, progress=not getattr(args, "no_progress", False))
    print(format_table(exp.summary_rows(res), exp.summary_headers(res)))
    for line in exp.summary_lines(res):
        print(line)
    exp.plot(res, png)
    print(f"wrote {png}")
    _write_json(
        args, res["figures"], {**res["meta"], "command": f"analyze {args.analysis}"}, res["series"]
    )
    return 0


def cmd_belief_shift(args) -> int:
    """``phyloc analyze belief-shift``: DiPNet Fig. 3 and its summary numbers (the
    ``belief_shift`` experiment, a recipe built from the flags)."""
    doc = {
        "kind": "belief_shift",
        "name": "analyze_belief_shift",
        "seed": 0,
        "system": {"n_subcarriers": args.subcarriers},
        "experiment": {"nu": args.nu},
    }
    flags = {
        "experiment.nu": {"flag": "--nu"},
        "system.n_subcarriers": {"flag": "--subcarriers"},
    }
    png = args.png or f"belief_shift_nu{args.nu:g}.png"
    print(f"belief shift (DiPNet §IV-B), ν = {args.nu:g}, N = {args.subcarriers}; [c0/B]")
    return _run_preset(args, doc, flags, png)


def cmd_cci(args) -> int:
    """``phyloc analyze cci``: DiPNet Fig. 2 for any scenarios, and its summary numbers (the
    ``cci`` experiment, a recipe built from the flags)."""
    from pathlib import Path

    n = args.subcarriers
    bw = 14.65e3 * n if args.bandwidth_hz is None else args.bandwidth_hz
    doc = {
        "kind": "cci",
        "name": "analyze_cci",
        "seed": args.seed,
        "system": {
            "n_subcarriers": n,
            "subcarrier_spacing_hz": bw / n if n else bw,
            "carrier_frequency_hz": args.carrier_hz,
        },
        "experiment": {
            "scenarios": list(args.scenarios),
            "links": args.links,
            "mc_points": args.mc_points,
            "distance_m": args.distance_m,
        },
    }
    flags = {
        "system.n_subcarriers": {"flag": "--subcarriers"},
        "system.subcarrier_spacing_hz": {"flag": "--bandwidth-hz", "arg": "bandwidth_hz"},
        "experiment.links": {"flag": "--links"},
        "experiment.mc_points": {"flag": "--mc-points"},
        "experiment.distance_m": {"flag": "--distance-m"},
        "experiment.scenarios": {"flag": "SCENARIO"},
    }
    label = "_".join(Path(s).stem for s in args.scenarios)
    return _run_preset(args, doc, flags, args.png or f"cci_{label}.png")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
