"""Recorded OFDM snapshots as phyloc datasets: ``phyloc import`` and ``phyloc export``.

:func:`import_arrays` reads plain arrays — an ``.npz`` file, a plain HDF5 file of arrays or a
mapping of names to arrays — checks every one of them, and writes a dataset of the schema in
``datasets/README.md`` (a master file and one shard) that ``phyloc evaluate``, ``phyloc info
--verify`` and :func:`phyloc.datasets.open` accept. The array names are the interface; the
section "Importing recorded snapshots" of ``datasets/README.md`` gives each one's shape, dtype
and units:

* required: ``received`` ``[K, L, N]`` complex (frequency-domain symbols ``R_n`` of every
  link and snapshot), ``links`` ``[L, 2]`` or ``[K, L, 2]`` (node u receives from node v),
  ``symbols`` ``[n, N]`` (pilots), ``is_anchor`` ``[n]``, ``subcarrier_spacing_hz``, ``ways``
  and the noise: ``noise_variance_w`` or ``temperature_k`` with ``noise_figure_db``;
* required with anchors unless ``positions`` is given: ``anchor_positions``
  ``[n_anchors, D]``;
* optional: ``link_mask`` ``[K, L]`` or ``link_count`` ``[K]`` (links that vary between
  snapshots), ground truth ``positions`` ``[K, n, D]`` and ``los`` ``[K, L]``,
  ``carrier_frequency_hz``, ``tx_power_dbm``, ``n_subcarriers``, ``dt_s``, ``dim`` and
  ``recipe`` (TOML text whose ``seed``, ``name``, ``[channel] scenario``, ``[ranging]``,
  ``[localization]`` and ``[experiment]`` the dataset keeps for ``phyloc evaluate``).

Every array may carry a leading realization axis ``R`` (then all per-realization arrays do).
A missing, mis-shaped or inconsistent array raises :class:`~phyloc.errors.ValidationError`
naming the array, the shape seen and the shape expected; nothing is written then. The checks
are the table of :mod:`phyloc.datasets.import_checks`
(:func:`~phyloc.datasets.import_checks.check_arrays`); this module reads the source, builds
the stored recipe and writes the dataset.

:func:`export_arrays` writes a dataset back to such arrays (realization axis included), so
``import_arrays(export_arrays(ds))`` stores the same received samples, pilots, links and
truth, and ``phyloc evaluate`` gives identical results on both files.

References
----------
The HDF Group, *HDF5 User's Guide*, https://docs.hdfgroup.org/; the h5py documentation,
https://docs.h5py.org/; NumPy, "numpy.savez" (the ``.npz`` format),
https://numpy.org/doc/stable/reference/generated/numpy.savez.html.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelSpec
from phyloc.config import Recipe, dumps_toml, load_recipe
from phyloc.datasets import schema as sc
from phyloc.datasets.files import fsync, output_lock, staged
from phyloc.datasets.import_checks import CheckedArrays, check_arrays
from phyloc.datasets.master import write_master
from phyloc.datasets.plan import DatasetPlan
from phyloc.datasets.shard import shard_attributes
from phyloc.datasets.spec import DatasetSpec
from phyloc.errors import ValidationError
from phyloc.network import NetworkSpec
from phyloc.phy.waveform import from_time_domain, to_time_domain
from phyloc.reporting import OutputExistsError

#: Default scenario label of an imported dataset (``[channel] scenario`` of its recipe): a
#: label in figure names only, nothing is simulated.
DEFAULT_SCENARIO = "awgn"


# -- reading the source ---------------------------------------------------------------------
def read_arrays(source) -> dict:
    """The arrays of ``source`` by name: an ``.npz`` file, a plain HDF5 file (datasets at the
    root; nested ones are named ``group/name``) or a mapping of names to array-likes.

    Raises
    ------
    DatasetError
        The file does not exist or is not readable as ``.npz`` or HDF5.
    ValidationError
        An array that cannot be read without pickling, or a phyloc dataset given as source.
    """
    if isinstance(source, Mapping):
        return {str(k): np.asarray(val) for k, val in source.items()}
    path = Path(source)
    why = v.unreadable_file(path)
    if why:
        raise sc.DatasetError(f"source {why} (give an .npz or an HDF5 file)")
    if h5py.is_hdf5(path):
        out = {}
        with h5py.File(path, "r") as f:
            if sc._text(f.attrs.get("format", "")).startswith(sc.MASTER_FORMAT):
                raise ValidationError(
                    "source",
                    str(path),
                    "is already a phyloc dataset: evaluate it directly, or export it first "
                    "(phyloc export) to get plain arrays",
                )
            outside = sc.outside_references(f, allow_virtual=False)
            if outside:
                raise ValidationError(
                    "source", str(path), f"refused: {outside} (import reads only the file given)"
                )

            def take(name, obj):
                if isinstance(obj, h5py.Dataset):
                    _check_size(name, obj.shape, obj.dtype, None)
                    data = obj[()]
                    if isinstance(data, bytes):
                        data = data.decode()
                    out[name] = np.asarray(data)

            f.visititems(take)
        return out
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise sc.DatasetError(
            f"cannot read {path} as .npz or HDF5 ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ValidationError("source", str(path), "an .npz file of named arrays, not one .npy")
    out = {}
    with z:
        for name in z.files:
            shape, dtype, stored = _npy_header(z, name)
            _check_size(name, shape, dtype, stored)
            try:
                out[name] = z[name]
            except ValueError:
                raise ValidationError(
                    name, "object array", "plain numeric or text arrays (no pickled objects)"
                ) from None
    return out


def _npy_header(z, name):
    """``(shape, dtype, bytes stored)`` of member ``name`` of the open ``.npz`` ``z``, read from
    its ``.npy`` header alone (nothing allocated); ``(None, None, None)`` when the header
    cannot be read (``z[name]`` then reports the problem)."""
    member = name if name in z.zip.namelist() else name + ".npy"
    try:
        info = z.zip.getinfo(member)
        with z.zip.open(member) as f:
            version = np.lib.format.read_magic(f)
            read = (
                np.lib.format.read_array_header_1_0
                if version == (1, 0)
                else np.lib.format.read_array_header_2_0
            )
            shape, _, dtype = read(f, max_header_size=1 << 20)
            return shape, dtype, info.file_size - f.tell()
    except (KeyError, ValueError, OSError, zipfile.BadZipFile):
        return None, None, None


def _memory_bytes() -> float:
    """This machine's physical memory [bytes] (inf where it cannot be read)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return math.inf


def _check_size(name, shape, dtype, stored) -> None:
    """Refuse array ``name`` from its declared ``shape`` and ``dtype`` before reading it: more
    bytes than its file member holds (``stored``; a crafted header), or more than this
    machine's memory."""
    if shape is None or dtype is None:
        return
    need = math.prod(int(x) for x in shape) * np.dtype(dtype).itemsize
    if stored is not None and need > stored:
        raise ValidationError(
            name,
            f"declared shape {tuple(shape)} of {np.dtype(dtype)} ({_human(need)})",
            f"its file member holds {_human(stored)} of data: a damaged or crafted header",
        )
    memory = _memory_bytes()
    if need > memory:
        raise ValidationError(
            name,
            f"shape {tuple(shape)} of {np.dtype(dtype)} ({_human(need)})",
            f"more than this machine's memory ({_human(memory)}); split the recording into "
            "smaller files",
        )


def _human(n: float) -> str:
    """A byte count with a binary unit: 7.11 PiB."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024:
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"


# -- the stored recipe ------------------------------------------------------------------------
def _base_recipe(recipe, arrays) -> Recipe | None:
    if recipe is None and "recipe" in arrays:
        a = np.asarray(arrays["recipe"])
        if a.size != 1 or a.dtype.kind not in "US":
            raise ValidationError(
                "recipe", f"{a.dtype} array of shape {a.shape}", "expected TOML text (a string)"
            )
        recipe = a.reshape(()).item()
        recipe = recipe.decode() if isinstance(recipe, bytes) else recipe
        if "=" not in recipe:
            raise ValidationError("recipe", recipe, "expected the TOML text of a recipe")
    if recipe is None or isinstance(recipe, Recipe):
        return recipe
    return load_recipe(recipe)


def _safe_name(text: str) -> str:
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_.") or "imported"
    return name


def _recipe_doc(base: Recipe | None, data: CheckedArrays, out: Path, source_label: str) -> dict:
    """The stored recipe: the user's seed, name and evaluation sections; [system], [network],
    [channel] and [dataset] describe the imported arrays."""
    from phyloc.localization import METHODS
    from phyloc.ranging.estimators import ORACLES

    R, K, _, _, n, dim = data.shape
    n_anchors = int(data.is_anchor[0].sum())
    sections = {} if base is None else base.sections
    chan = dict(sections.get("channel", {}))
    scenario = chan.get("scenario", DEFAULT_SCENARIO)
    ranging = "two_way" if data.ways == 2 else "one_way"
    if "ranging" in chan and chan["ranging"] != ranging:
        raise ValidationError(
            "ways",
            data.ways,
            f"contradicts [channel] ranging = {chan['ranging']!r} of the recipe",
        )
    network = {"n_agents": n - n_anchors, "dim": dim, "on_isolated": "allow"}
    if n_anchors:
        network.update(anchors=n_anchors, anchor_layout="uniform")
    motion = {"n_snapshots": K}
    if data.dt_s is not None:
        motion["dt_s"] = data.dt_s
    network["motion"] = motion
    doc = {
        "kind": "dataset",
        "name": base.name if base is not None else _safe_name(out.stem),
        "seed": base.seed if base is not None else 0,
        "description": (base.description if base is not None else "")
        or f"recorded snapshots imported from {source_label}",
        "system": data.system.to_dict(),
        "network": network,
        "channel": {"scenario": scenario, "ranging": ranging},
        "dataset": {"realizations": R, "shard_size": R},
    }
    for s in ("ranging", "localization", "experiment"):
        if s in sections:
            doc[s] = dict(sections[s])
    # methods that need ground truth the arrays lack
    experiment = dict(doc.get("experiment", {}))
    oracle_inputs = {f"ranges:{o}" for o in ORACLES}
    direct = METHODS.family("direct")
    listed = experiment.get("methods")
    methods = list(listed) if listed is not None else list(direct)
    needs_los = [m for m in methods if m in METHODS and METHODS[m].inputs in oracle_inputs]
    if data.los is None and needs_los:
        if listed is not None:
            raise ValidationError(
                "los",
                "missing",
                f"[experiment] methods lists {needs_los[0]}, an oracle that needs the "
                "ground-truth LOS flags: supply los [K, L] (1 for LOS) or drop the method",
            )
        experiment["methods"] = [m for m in methods if m not in needs_los]
        doc["experiment"] = experiment
    inits = experiment.get("inits", ["truth_free"])
    if "positions" not in data.truth and "informed" in inits:
        raise ValidationError(
            "positions",
            "missing",
            "[experiment] inits lists 'informed', which starts from the ground truth",
        )
    return doc


def _recipe_text(doc: dict, source_label: str) -> str:
    head = (
        f"# Imported by phyloc import from {source_label}. [system], [network], [channel] and\n"
        "# [dataset] describe the imported arrays: nothing is simulated, and phyloc generate\n"
        "# cannot rebuild this dataset. [channel] scenario is a label in figure names.\n"
    )
    return head + dumps_toml(doc)


# -- writing --------------------------------------------------------------------------------
def _clear_output(out: Path, sdir: Path) -> None:
    """Remove an existing import output (``--force``): the master and the shard folder's own
    files; a folder holding anything else is left alone and refused."""
    if sdir.is_dir():
        ours = re.compile(r"^(shard-\d{5}\.h5|\.shard-\d{5}\.h5\.tmp-.*|\.lock)$")
        others = [p.name for p in sdir.iterdir() if not ours.match(p.name)]
        if others:
            raise OutputExistsError(
                f"{sdir} (it holds files phyloc did not write, e.g. {others[0]})"
            )
        for p in sdir.iterdir():
            p.unlink()
        sdir.rmdir()
    if out.exists():
        out.unlink()


def _write_imported_shard(path: Path, data: CheckedArrays, fingerprint: str, seed: int) -> dict:
    """Write the one shard of an imported dataset atomically; return its shard-table row."""
    R, K, L, N, n, dim = data.shape
    system = data.system
    M = system.n_samples
    arrays = sc.arrays_for({})
    dims = {
        "realization": R,
        "snapshot": K,
        "node": n,
        "coordinate": dim,
        "link": L,
        "end": 2,
        "subcarrier": N,
        "sample": M,
    }
    small = {
        a.name: np.full(a.shape(dims), a.fill, dtype=a.dtype)
        for a in arrays
        if a.role != "path" and a.name not in ("received", "symbols")
    }
    small["nodes/positions"][:] = data.positions
    small["nodes/is_anchor"][:] = data.is_anchor
    small["links/count"][:] = data.counts
    small["links/pairs"][:] = data.pairs
    small["links/valid"][:] = np.arange(L) < data.counts[..., None]
    if data.los is not None:
        small["channel/los"][:] = data.los
    small["channel/paths/start"][:] = 0
    small["channel/paths/count"][:] = 0
    small["channel/paths/base"][:] = 0
    if "positions" in data.truth:
        for r in range(R):
            for t in range(K):
                c = data.counts[r, t]
                u, v = data.pairs[r, t, :c].T
                diff = data.positions[r, t, u] - data.positions[r, t, v]
                small["channel/distance_m"][r, t, :c] = np.sqrt((diff**2).sum(axis=1))
    small["channel/paths/delays_s"] = np.zeros(0)
    small["channel/paths/gains"] = np.zeros(0, np.complex128)
    samples = np.zeros((R, K, L, M), np.complex64)
    for r in range(R):
        for t in range(K):
            c = data.counts[r, t]
            samples[r, t, :c] = to_time_domain(data.received[r, t, :c], system)
    small["received"] = samples
    small["symbols"] = data.symbols
    with staged(path) as tmp:
        with h5py.File(tmp, "w") as f:
            for a in arrays:
                value = small[a.name]
                kw = {}
                if a.name == "received":
                    kw["chunks"] = (1, 1, L, M)
                elif a.name == "symbols":
                    kw["chunks"] = (1, n, N)
                d = f.create_dataset(a.name, data=value, **kw)
                d.attrs["sha256"] = sc.sha256_array(value)
                a.annotate(d)
            f.attrs.update(
                shard_attributes(
                    fingerprint=fingerprint,
                    seed=seed,
                    index=0,
                    start=0,
                    stop=R,
                    max_links=L,
                    n_links=int(data.counts.sum()),
                    n_paths=0,
                )
            )
            f.attrs["complete"] = 1
        fsync(tmp)
        os.replace(tmp, path)
    with h5py.File(path, "r") as f:
        record = sc.shard_record(f, path, arrays)
    record["file_sha256"] = sc.sha256_file(path)
    return record


def import_arrays(source, out, *, recipe=None, force: bool = False) -> Path:
    """Write recorded OFDM snapshots (raw arrays) into a phyloc dataset (``phyloc import``).

    Parameters
    ----------
    source : str, Path or mapping
        An ``.npz`` file, a plain HDF5 file of arrays, or a mapping of names to arrays. The
        names and shapes are those of :data:`INPUTS` (``datasets/README.md``, "Importing
        recorded snapshots"); every array may carry a leading realization axis.
    out : str or Path
        The master file to write (``OUT.h5``); its shard goes to ``OUT.h5.shards/``.
    recipe : Recipe, path or TOML text, optional
        Supplies ``seed``, ``name``, ``description``, ``[channel] scenario`` (a label) and the
        ``[ranging]``, ``[localization]`` and ``[experiment]`` sections that ``phyloc
        evaluate`` reads from the dataset. Default: the source's ``recipe`` text if it has one,
        else seed 0, the output's stem as name and phyloc's defaults.
    force : bool
        Replace an existing output (the master and its shard folder). Without it an existing
        output is an error and is left untouched.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    ValidationError
        A missing, unknown, mis-shaped or inconsistent array (the message names it, with the
        shape seen and the shape expected), or a recipe whose methods need ground truth the
        arrays lack (the LOS oracle ``sage_los`` needs ``los``; the ``informed`` start needs
        ``positions``). Nothing is written.
    OutputExistsError
        ``out`` or its shard folder exists and ``force`` is False.
    DatasetError
        The source cannot be read.

    Notes
    -----
    The received symbols are stored as the schema's complex64 time samples with oversampling
    1 (``to_time_domain``); reading them back (``from_time_domain``) gives ``R_n`` to within
    complex64 rounding. Without ``positions`` the agents' positions are stored as NaN:
    ``phyloc info`` and :meth:`Dataset.snapshot` work, ``phyloc evaluate`` (which scores
    against the truth) refuses the file.

    Examples
    --------
    Two agents and one anchor, one snapshot, noise only (a smoke example; see
    ``tests/test_import.py`` for a round trip through :func:`export_arrays`):

    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import phyloc.datasets as pds
    >>> rng = np.random.default_rng(0)
    >>> N = 33
    >>> links = np.array([[0, 1], [1, 0], [0, 2], [1, 2]])   # (receiver, transmitter)
    >>> arrays = {
    ...     "received": (rng.normal(size=(1, 4, N)) + 1j * rng.normal(size=(1, 4, N))) * 1e-6,
    ...     "links": links,
    ...     "symbols": np.exp(2j * np.pi * rng.integers(4, size=(3, N)) / 4),
    ...     "is_anchor": np.array([0, 0, 1]),
    ...     "anchor_positions": np.array([[10.0, 5.0]]),
    ...     "subcarrier_spacing_hz": 1e6,
    ...     "noise_variance_w": 2e-12,
    ...     "ways": 1,
    ... }
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     out = pds.import_arrays(arrays, pathlib.Path(tmp) / "rec.h5")
    ...     with pds.open(out) as ds:
    ...         snap = ds.snapshot(0, 0)
    ...         sigma2 = ds.system.noise_power_w
    ...     ok = pds.verify(out)["ok"]
    >>> snap.links.tolist(), snap.received.shape, round(sigma2 / 2e-12, 12), ok
    ([[0, 1], [0, 2], [1, 0], [1, 2]], (4, 33), 1.0, True)
    """
    out = Path(out)
    label = "arrays" if isinstance(source, Mapping) else Path(source).name
    if not isinstance(source, Mapping) and out.resolve() == Path(source).resolve():
        raise ValidationError("out", str(out), "must differ from the source file")
    if out.is_dir():
        raise ValidationError("out", str(out), "is a folder; give the path of an .h5 file")
    sdir = sc.shard_dir(out)
    if (out.exists() or sdir.exists()) and not force:
        raise OutputExistsError(out)
    arrays = read_arrays(source)
    base = _base_recipe(recipe, arrays)
    arrays.pop("recipe", None)
    data = check_arrays(arrays)
    doc = _recipe_doc(base, data, out, label)
    text = _recipe_text(doc, label)
    stored = load_recipe(text)
    network = NetworkSpec.from_dict(doc["network"])
    channel = ChannelSpec.from_dict(doc["channel"])
    dspec = DatasetSpec.from_dict(doc["dataset"])
    h = hashlib.sha256(text.encode())
    for a in (data.received, data.pairs, data.symbols, data.positions, data.counts):
        h.update(sc.sha256_array(a).encode())
    canon = {"schema_major": sc.SCHEMA_MAJOR, "imported": h.hexdigest()}
    fingerprint = hashlib.sha256(
        json.dumps(canon, sort_keys=True, separators=(",", ":")).encode()
    ).hexdigest()
    plan = DatasetPlan(stored, data.system, network, channel, dspec, fingerprint, {})
    if force:
        _clear_output(out, sdir)
    elif out.exists() or sdir.exists():  # appeared while we checked
        raise OutputExistsError(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sdir.mkdir()
    with output_lock(sdir, out):
        record = _write_imported_shard(sdir / sc.shard_name(0), data, fingerprint, stored.seed)
        provenance = {
            "source": "imported",
            "imported_from": label,
            "truth": ",".join(data.truth),
            "node_order": data.node_order,
        }
        if data.dt_s is None:
            provenance["dt_s"] = math.nan
        write_master(out, plan, [record], attrs=provenance)
    return out


# -- export ---------------------------------------------------------------------------------
def export_arrays(dataset_path, out, *, force: bool = False) -> Path:
    """Write a dataset's waveforms and truth as the raw arrays :func:`import_arrays` reads.

    Every array carries the leading realization axis: ``received`` ``[R, K, L, N]``
    complex128 (``from_time_domain`` of the stored samples), ``links`` ``[R, K, L, 2]``,
    ``link_mask`` ``[R, K, L]``, ``symbols``, ``is_anchor``, ``anchor_positions`` (with
    anchors), ``positions`` and ``los`` (unless the dataset was imported without them), the
    system parameters (``n_subcarriers``, ``subcarrier_spacing_hz``, ``carrier_frequency_hz``,
    ``tx_power_dbm``, ``temperature_k``, ``noise_figure_db``), ``ways``, ``dt_s`` (several
    snapshots), ``dim`` and the stored ``recipe`` text.

    Parameters
    ----------
    dataset_path : str or Path
        A complete dataset (master file).
    out : str or Path
        ``.npz`` or ``.h5``/``.hdf5`` (a plain HDF5 file, one dataset per array).
    force : bool
        Replace an existing ``out``.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    OutputExistsError
        ``out`` exists and ``force`` is False.
    ValidationError
        ``out`` has another suffix.
    DatasetError
        The dataset is missing, unreadable or incomplete.
    """
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".npz", ".h5", ".hdf5"):
        raise ValidationError("out", str(out), "must end in .npz, .h5 or .hdf5")
    if out.exists() and not force:
        raise OutputExistsError(out)
    from phyloc.datasets.reader import open_dataset

    with open_dataset(dataset_path) as ds:
        for r in range(ds.n_realizations):
            ds._realization(r)  # a clear error for a realization that is not stored
        f = ds.file
        system = ds.system
        truth = sc._text(f.attrs.get("truth", "positions,los")).split(",")
        is_anchor = f["nodes/is_anchor"][...].astype(bool)
        positions = f["nodes/positions"][...]
        arrays = {
            "received": from_time_domain(f["received"][...], system),
            "links": f["links/pairs"][...].astype(np.int64),
            "link_mask": f["links/valid"][...].astype(bool),
            "symbols": f["symbols"][...],
            "is_anchor": is_anchor,
        }
        n_anchors = int(is_anchor[0].sum())
        if n_anchors:
            arrays["anchor_positions"] = np.stack(
                [positions[r, 0][is_anchor[r]] for r in range(ds.n_realizations)]
            )
        if "positions" in truth:
            arrays["positions"] = positions
        if "los" in truth:
            arrays["los"] = f["channel/los"][...].astype(bool)
        for k in (
            "n_subcarriers",
            "subcarrier_spacing_hz",
            "carrier_frequency_hz",
            "tx_power_dbm",
            "temperature_k",
            "noise_figure_db",
        ):
            arrays[k] = np.asarray(getattr(system, k))
        arrays["ways"] = np.asarray(ds.ways)
        arrays["dim"] = np.asarray(ds.dim)
        if ds.dt_s is not None:
            arrays["dt_s"] = np.asarray(ds.dt_s)
        arrays["recipe"] = np.asarray(ds.recipe)
    out.parent.mkdir(parents=True, exist_ok=True)
    with staged(out) as tmp:
        if suffix == ".npz":
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
        else:
            with h5py.File(tmp, "w") as h:
                for k, a in arrays.items():
                    if a.dtype.kind == "U":
                        h.create_dataset(k, data=str(a), dtype=h5py.string_dtype())
                    else:
                        h.create_dataset(k, data=a)
        os.replace(tmp, out)
    return out


__all__ = ["DEFAULT_SCENARIO", "export_arrays", "import_arrays", "read_arrays"]
