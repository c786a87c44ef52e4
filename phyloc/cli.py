"""The ``phyloc`` command line.

Commands
    ``phyloc bench [phy|channels|all] [--quick] [--json PATH]``
        Run benchmarks; print cost per unit of work and ratios to references.
    ``phyloc evaluate RECIPE [--fast] [--out DIR] [--json PATH] [--workers N | --scheduler ADDR]``
        Run an experiment recipe; write ``results.json``, the recipe and a PNG into DIR.
    ``phyloc channel-stats SCENARIO [--square SIDE_M] [--links N] [--seed S] [--png PATH]
    [--json PATH]``
        Draw links of a channel scenario and compare realized statistics with its table.

Errors a user can cause are printed as one line without a traceback (exit status 2).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time

from phyloc.errors import PhylocError

BENCHMARKS = {
    "phy": "phyloc.benchmarks.bench_phy",
    "channels": "phyloc.benchmarks.bench_channels",
    "ranging": "phyloc.benchmarks.bench_ranging",
    "dipnet": "phyloc.benchmarks.bench_dipnet",
    "datasets": "phyloc.benchmarks.bench_datasets",
}


def _add_json(p):
    p.add_argument("--json", metavar="PATH", help="also write the figures as JSON to PATH")
    p.add_argument("--force", action="store_true", help="replace an existing --json/--png file")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``phyloc`` command."""
    from phyloc import __version__

    parser = argparse.ArgumentParser(
        prog="phyloc",
        description="Signal-level PHY simulation and direct localization of wireless networks.",
    )
    parser.add_argument("--version", action="version", version=f"phyloc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    b = sub.add_parser("bench", help="run benchmarks and print their cost per unit of work")
    b.add_argument(
        "suite",
        nargs="?",
        default="phy",
        choices=[*BENCHMARKS, "all"],
        help="which benchmark suite (default: phy)",
    )
    b.add_argument("--quick", action="store_true", help="shorter runs (less precise)")
    _add_json(b)
    b.set_defaults(func=cmd_bench)

    e = sub.add_parser("evaluate", help="run an experiment recipe (datasets/*.toml)")
    e.add_argument("recipe", help="path of a recipe TOML file")
    e.add_argument(
        "--fast", action="store_true", help="the recipe's [experiment.fast] setting (small, for CI)"
    )
    e.add_argument(
        "--out",
        metavar="DIR",
        default=None,
        help="results folder (default results/<recipe name>[-fast])",
    )
    e.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="run tasks on a local Dask cluster of N processes (default: in-process)",
    )
    e.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run tasks on an existing Dask scheduler",
    )
    e.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_json(e)
    e.set_defaults(func=cmd_evaluate)

    c = sub.add_parser(
        "channel-stats",
        help="draw links of a channel scenario and compare their statistics with its table",
    )
    c.add_argument("scenario", help="scenario name (e.g. winner2_c2) or a path to a TOML file")
    c.add_argument(
        "--square",
        type=float,
        default=100.0,
        metavar="SIDE_M",
        help="side of the square the link end points are drawn in [m] (default 100)",
    )
    c.add_argument(
        "--links",
        type=int,
        default=20000,
        metavar="N",
        help="number of links to draw (default 20000)",
    )
    c.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    c.add_argument(
        "--png",
        metavar="PATH",
        default=None,
        help="figure of example power-delay profiles (default channel_stats_<scenario>.png)",
    )
    _add_json(c)
    c.set_defaults(func=cmd_channel_stats)
    return parser


def main(argv=None) -> int:
    """Entry point of the console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PhylocError as exc:
        print(f"phyloc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("phyloc: interrupted", file=sys.stderr)
        return 130


# -- bench -----------------------------------------------------------------------------------
def cmd_bench(args) -> int:
    """``phyloc bench``: run the suites, print their tables, optionally write JSON."""
    from phyloc.reporting import OutputExistsError, machine_meta, write_json

    if args.json and not args.force:
        from pathlib import Path

        if Path(args.json).exists():  # fail before spending a minute on the benchmark
            raise OutputExistsError(args.json)
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
    if args.json:
        meta = {
            "command": "bench",
            "suite": args.suite,
            "quick": bool(args.quick),
            "seconds": time.perf_counter() - t0,
            "machine": machine_meta(),
        }
        path = write_json(args.json, figures, meta, force=args.force)
        print(f"wrote {path}")
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
EXPERIMENTS = {
    "ranging": "phyloc.evaluation.ranging_experiment",
    "localization": "phyloc.evaluation.localization_experiment",
}


def cmd_evaluate(args) -> int:
    """``phyloc evaluate``: run a recipe, print its table, write the results folder."""
    from pathlib import Path

    from phyloc.config import load_recipe
    from phyloc.reporting import OutputExistsError, format_table, machine_meta, write_json

    recipe = load_recipe(args.recipe)
    exp = importlib.import_module(EXPERIMENTS[recipe.kind])
    out = Path(args.out or Path("results") / (recipe.name + ("-fast" if args.fast else "")))
    if out.exists() and any(out.iterdir()) and not args.force:
        raise OutputExistsError(out)
    if args.json and Path(args.json).exists() and not args.force:
        raise OutputExistsError(args.json)
    t0 = time.perf_counter()
    res = exp.run(
        recipe,
        fast=args.fast,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    res["meta"].update(
        {"seconds": time.perf_counter() - t0, "machine": machine_meta(), "recipe_text": recipe.text}
    )
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "results.json", res["figures"], res["meta"], res["series"], force=True)
    (out / "recipe.toml").write_text(recipe.text)
    png = out / f"{recipe.name}.png"
    exp.plot(res, png)
    print(f"{recipe.name}{' (fast)' if args.fast else ''}: {res['meta']['seconds']:.1f} s")
    headers = exp.summary_headers(res) if hasattr(exp, "summary_headers") else exp.SUMMARY_HEADERS
    print(format_table(exp.summary_rows(res), headers))
    for line in getattr(exp, "summary_lines", lambda r: [])(res):
        print(line)
    print(f"wrote {out / 'results.json'}, {png}")
    if args.json:
        write_json(args.json, res["figures"], res["meta"], res["series"], force=args.force)
        print(f"wrote {args.json}")
    return 0


# -- channel-stats ---------------------------------------------------------------------------
def cmd_channel_stats(args) -> int:
    """``phyloc channel-stats``: realized statistics of a scenario versus its table."""
    from pathlib import Path

    import numpy as np

    from phyloc.channels.stats import channel_stats, plot_power_delay_profiles
    from phyloc.reporting import OutputExistsError, format_table, machine_meta, write_json

    png = Path(args.png or f"channel_stats_{Path(args.scenario).stem}.png")
    for p in (args.json, png):
        if p and Path(p).exists() and not args.force:
            raise OutputExistsError(p)
    rng = np.random.default_rng(args.seed)
    res = channel_stats(args.scenario, square_m=args.square, n_links=args.links, rng=rng)
    print(
        f"channel statistics of {args.scenario}: {args.links} links, "
        f"end points uniform in a {args.square:g} m square, seed {args.seed}"
    )
    print(format_table(res["table"], ["quantity", "realized", "table"]))
    plot_power_delay_profiles(res["draw"], png)
    print(f"wrote {png}")
    if args.json:
        meta = {
            "command": "channel-stats",
            "scenario": args.scenario,
            "seed": args.seed,
            "links": args.links,
            "square_m": args.square,
            "machine": machine_meta(),
        }
        path = write_json(args.json, res["figures"], meta, res.get("series"), force=args.force)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
