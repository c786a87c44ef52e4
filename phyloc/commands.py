"""The handlers of the ``phyloc`` commands (:mod:`phyloc.cli` parses the arguments and calls
them): each validates its outputs before any work, runs the work through the package, prints
its table and writes what ``--json`` asks for.

References
----------
Python Software Foundation, "argparse — Parser for command-line options, arguments and
sub-commands", https://docs.python.org/3/library/argparse.html.
"""

from __future__ import annotations

import hashlib
import importlib
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
    "memory_large": "phyloc.benchmarks.bench_memory_large",
    "sionna": "phyloc.benchmarks.bench_sionna",
}

#: Suites ``bench all`` leaves out: ``memory_large`` writes about 8 GB and runs ~20 minutes.
NOT_IN_ALL = ("memory_large",)


# -- bench -----------------------------------------------------------------------------------
def cmd_bench(args) -> int:
    """``phyloc bench``: run the suites, print their tables, optionally write JSON."""
    _check_outputs(args)  # fail before spending a minute on the benchmark
    suites = [s for s in BENCHMARKS if s not in NOT_IN_ALL] if args.suite == "all" else [args.suite]
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


# -- claims ----------------------------------------------------------------------------------
def cmd_claims(args) -> int:
    """``phyloc claims``: every claim of the ledger with its verdict recomputed from the stored
    runs; exits 1 when a recomputed verdict no longer matches the ledger."""
    from phyloc.evaluation.claims import check_ledger
    from phyloc.reporting import format_table

    _check_outputs(args)
    report = check_ledger(args.ledger, args.results)
    if args.paper:
        report = [r for r in report if r["paper"].lower() == args.paper.lower()]
        if not report:
            raise ValidationError("--paper", args.paper, "a paper the ledger names")
    rows = [
        (
            r["id"],
            r["paper"],
            r["verdict_now"] + ("" if r["matches"] else f" (ledger: {r['verdict']})"),
            _interval_text(r["outcomes"]),
            r["run"],
        )
        for r in report
    ]
    print(format_table(rows, ["claim", "paper", "verdict", "95 % interval", "stored run"]))
    changed = [r["id"] for r in report if not r["matches"]]
    counts = {v: sum(r["verdict_now"] == v for r in report) for v in ("holds", "differs")}
    undecided = len(report) - sum(counts.values())
    print(
        f"{len(report)} claims: {counts['holds']} hold, {counts['differs']} differ, "
        f"{undecided} undecided"
    )
    figures = {f"{r['id']}.matches": float(r["matches"]) for r in report}
    _write_json(args, figures, {"command": "claims", "claims": report})
    if changed:
        print(
            f"phyloc: error: {len(changed)} verdict(s) no longer match the ledger: "
            f"{', '.join(changed)}; update {args.ledger} deliberately or find what changed",
            file=sys.stderr,
        )
        return 1
    return 0


def _interval_text(outcomes) -> str:
    """The interval of a one-check claim, or the range of the checks of a claim with ``each``."""
    if len(outcomes) == 1:
        o = outcomes[0]
        if o["exact"]:
            return f"{o['value']:.3g} (exact)"
        return f"{o['value']:.3g} [{o['ci_low']:.3g}, {o['ci_high']:.3g}]"
    return f"{len(outcomes)} checks"


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
    from phyloc.reporting import OutputExistsError

    if args.plugin:
        from phyloc.localization.registry import add_plugins

        add_plugins(args.plugin)
        if args.scheduler:
            _check_workers_know_plugins(args.scheduler)
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
        if (tasks_dir / "run.json").exists():  # an interrupted run's tasks are kept there
            raise PhylocError(
                f"{out} holds an unfinished run (its finished tasks are kept in {tasks_dir}); "
                "pass --resume to finish it, or --force to discard them and start over"
            )
        raise OutputExistsError(out)
    if args.json and Path(args.json).exists() and not args.force:
        raise OutputExistsError(args.json)
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
        # --force discards old tasks only under the folder's lock: never those of a live run
        store = TaskStore(tasks_dir, identity, resume=args.resume, discard=args.force)
    except TaskStoreMismatch as exc:
        raise PhylocError(
            f"--resume: the unfinished run in {out} differs in {exc} (code: phyloc's sources "
            "changed since it started; recipe_sha256/source/fast: another recipe or setting); "
            "finish it with the code and recipe that started it, or start over with --force"
        ) from None
    except TaskStoreBusy as exc:
        raise PhylocError(
            f"another phyloc evaluate is running into {out} ({exc}); nothing was changed there "
            "(--force does not touch a folder a live run holds): wait for it, or stop it and "
            "run this command again with --resume"
        ) from None
    try:
        with task_store(store, close=False):  # the lock is held until the results are written
            res = exp.run(recipe, **kw) if recipe is not None else exp.run_dataset(source, **kw)
    except BaseException:
        if store.invocations == 1 and store.computed == 0:  # nothing to resume: leave no trace
            store.finish()
            if not out_existed and out.exists() and not any(out.iterdir()):
                out.rmdir()
        else:
            store.close()
        raise
    try:
        return _write_evaluation(args, exp, res, store, out, name, text, t0, verify_s)
    except BaseException:
        store.close()  # the tasks stay for --resume
        raise


def _check_workers_know_plugins(scheduler: str) -> None:
    """Workers started by hand import plugins only from their own ``PHYLOC_PLUGINS``: refuse
    a run whose workers lack a plugin method of this process, saying how to start them."""
    import os

    from phyloc.localization.registry import PLUGINS_ENV, method_names, plugin_methods
    from phyloc.parallel import connect

    wanted = plugin_methods()
    if not wanted:
        return
    with connect(scheduler) as client:
        known = client.run(method_names)
    lacking = sorted(w for w, names in known.items() if not set(wanted) <= set(names))
    if lacking:
        raise PhylocError(
            f"{len(lacking)} of the {len(known)} workers of {scheduler} do not know the plugin "
            f"method(s) {', '.join(wanted)} (e.g. {lacking[0]}): start each worker with the "
            f"plugin, e.g. {PLUGINS_ENV}={os.environ.get(PLUGINS_ENV, '')} dask worker "
            f"{scheduler}"
        )


def _write_evaluation(args, exp, res, store, out, name, text, t0, verify_s) -> int:
    """Write a finished evaluation's results (its task store still locked), print its table,
    then delete the stored tasks."""
    from phyloc.reporting import format_table, machine_meta, write_json

    wall = time.perf_counter() - t0
    if store.invocations > 1:
        print(
            f"resumed: {store.reused} finished tasks read back from {store.dir}, "
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
    store.finish()  # the run is complete: its results are in results.json
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
    shards = res.pop("shards", None) if isinstance(res.get("shards"), list) else None
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
    meta = {"command": "info", "dataset": str(args.dataset), "info": flat}
    if shards is not None:  # --verify: every shard's status and recorded digest
        meta["shards"] = shards
    _write_json(args, figs, meta)
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

    t0 = time.perf_counter()
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
    gen = args.parse_args(
        ["generate", str(recipe_path), "-o", str(h5), *common, *(["--resume"] * h5.exists())]
    )
    cmd_generate(gen)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    out = root / f"results-{stamp}"
    print(f"\n== 2/2 evaluate DiPNet and two-step methods on {h5} ==", flush=True)
    ev = args.parse_args(["evaluate", str(h5), "--out", str(out), *common])
    del recipe
    status = cmd_evaluate(ev)
    print(
        f"quickstart: {time.perf_counter() - t0:.0f} s in all (a first run includes compiling "
        "the Numba kernels, which later runs load from the cache; the runtimes above leave "
        "compilation out)"
    )
    return status


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


def cmd_channel_compare(args) -> int:
    """``phyloc channel-compare``: phyloc's TR 38.901 scenarios against Sionna's, one table per
    scenario and LOS state, a figure and (``--json``) every row."""
    from pathlib import Path

    from phyloc.channels import sionna_compare as sc
    from phyloc.channels import sionna_report as sr

    names = sc.check_arguments(args.scenarios, args.links, args.carrier_frequency_hz)
    label = "all" if args.scenarios == ["all"] else "_".join(names)
    png = Path(args.png or f"channel_compare_{label}.png")
    _check_outputs(args, png)
    sc.require_sionna()  # one line naming pip install sionna, before any work
    t0 = time.perf_counter()
    results = []
    for name in names:
        res = sc.compare(
            name,
            n_links=args.links,
            carrier_frequency_hz=args.carrier_frequency_hz,
            seed=args.seed,
        )
        print(sr.format_comparison(res), end="\n\n", flush=True)
        results.append(res)
    counts = sr.verdict_counts(results)
    print(
        f"{len(names)} scenario(s): {counts['agrees']} statistics agree, {counts['DIFFERS']} "
        f"differ, {counts['—']} without a test (level {sc.ALPHA:g} per statistic); "
        f"{time.perf_counter() - t0:.0f} s"
    )
    png.parent.mkdir(parents=True, exist_ok=True)
    sr.plot_comparison(results, png)
    print(f"wrote {png}")
    meta = {
        "command": "channel-compare",
        "scenarios": names,
        "links": args.links,
        "carrier_frequency_hz": args.carrier_frequency_hz,
        "seed": args.seed,
        "seconds": time.perf_counter() - t0,
    }
    figures, meta, series = sr.to_json(results, meta)
    _write_json(args, figures, meta, series)
    return 0


def _check_outputs(args, *paths) -> None:
    """Refuse, before any work, to overwrite ``--json`` or any of ``paths`` without
    ``--force``, and any of them that cannot be written (a folder, a missing or read-only
    parent), so that a command writes all its outputs or none."""
    from pathlib import Path

    from phyloc.reporting import OutputExistsError

    for p in (getattr(args, "json", None), *paths):
        if not p:
            continue
        p = Path(p)
        if p.is_dir():
            raise PhylocError(f"cannot write {p}: it is a folder; give a file path")
        if p.exists() and not args.force:
            raise OutputExistsError(p)
        why = _unwritable(p)
        if why:
            raise PhylocError(f"cannot write {p}: {why}; nothing was written")


def _unwritable(path) -> str:
    """Why ``path`` could not be created or replaced by this process ("" if it can): its
    first existing ancestor must be a writable folder (missing folders below it are made)."""
    import os

    if path.exists():
        return "" if os.access(path, os.W_OK) else "the file is read-only"
    parent = path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"{parent} is a file, not a folder"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"the folder {parent} is not writable"
    return ""


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
