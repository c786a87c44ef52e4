"""Reading waveform datasets: lazy arrays, snapshots for localizers, ``info``.

Typical use (the package docstring of :mod:`phyloc.datasets` has a runnable example)::

    with open_dataset("c2.h5") as ds:
        snap = ds.snapshot(0, 0)                               # realization 0, snapshot 0
        R, S, tx = snap.received, snap.symbols, snap.tx_index  # what a localizer needs
        table = correlation_tables(R, S, ds.system, tx_index=tx)

Every array of the schema (``datasets/README.md``) is available lazily as an ``h5py.Dataset``
(``ds["received"]``, ``ds.arrays``); :meth:`Dataset.snapshot` and :meth:`Dataset.realization`
read what one snapshot or one realization needs, and the iterators walk them in order.
:func:`~phyloc.datasets.integrity.info` summarizes a dataset and checks its integrity
(:mod:`phyloc.datasets.integrity`).

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path, PurePosixPath

import h5py
import numpy as np

from phyloc import _validate as v
from phyloc.channels import ChannelDraw
from phyloc.datasets import schema as sc
from phyloc.datasets.simulate import Realization
from phyloc.errors import ValidationError
from phyloc.network import Network
from phyloc.phy.paths import PathSet
from phyloc.phy.system import OFDMSystem
from phyloc.phy.waveform import from_time_domain


@dataclass(frozen=True, eq=False)
class Snapshot:
    """What a localizer needs from one (realization, snapshot) of a dataset.

    Attributes
    ----------
    realization, snapshot : int
    system : OFDMSystem
    positions : [n_nodes, dim] float64
        True positions [m].
    is_anchor : [n_nodes] bool
    links : [n_links, 2] int64
        Directed links (u, v): u receives from v.
    samples : [n_links, os·N] complex64
        Received time-domain samples ``r(iT)`` as stored [√W].
    symbols : [n_nodes, N] complex128
        Pilot symbols of every node as transmitter.
    los : [n_links] bool
    nlos_bias_s, distance_m, path_loss_db, shadowing_db, received_power_w, snr_db : [n_links]
        Channel truth per link (s, m, dB, dB, W, dB; ``snr_db`` is per sample).
    paths : PathSet
        Multipath components of every link (delays [s], gains [√W]).
    ways : int
        1 (one-way) or 2 (two-way ranging: delays are round trips).
    velocities : [n_nodes, dim] float64 or None
        [m/s] (CV/CA and waypoint motion only).
    """

    realization: int
    snapshot: int
    system: OFDMSystem
    positions: np.ndarray
    is_anchor: np.ndarray
    links: np.ndarray
    samples: np.ndarray
    symbols: np.ndarray
    los: np.ndarray
    nlos_bias_s: np.ndarray
    distance_m: np.ndarray
    path_loss_db: np.ndarray
    shadowing_db: np.ndarray
    received_power_w: np.ndarray
    snr_db: np.ndarray
    paths: PathSet
    ways: int
    velocities: np.ndarray | None = None

    @property
    def n_links(self) -> int:
        """Number of directed links."""
        return self.links.shape[0]

    @property
    def tx_index(self) -> np.ndarray:
        """Transmitter of each link (row of :attr:`symbols`), ``links[:, 1]``."""
        return self.links[:, 1]

    @property
    def rx_index(self) -> np.ndarray:
        """Receiver of each link, ``links[:, 0]``."""
        return self.links[:, 0]

    @cached_property
    def received(self) -> np.ndarray:
        """Frequency-domain received symbols ``R_n``, ``[n_links, N]`` complex128
        (:func:`~phyloc.phy.waveform.from_time_domain` of :attr:`samples`)."""
        return from_time_domain(self.samples, self.system)


#: What h5py raises when a file's bytes are damaged: a missing key or attribute, an
#: undecodable type or a broken B-tree (phyloc turns them into :class:`DatasetError`).
_CORRUPT = (KeyError, ValueError, TypeError, RuntimeError, OSError)


@contextlib.contextmanager
def _master_read(path):
    """Turn h5py's errors while reading a damaged master into one :class:`DatasetError`."""
    try:
        yield
    except _CORRUPT as exc:
        raise sc.DatasetError(
            f"{path}: the master file is corrupt ({type(exc).__name__}: {exc}); "
            f"`phyloc generate RECIPE -o {path} --resume` rebuilds it from its shards"
        ) from None


class Dataset:
    """An open phyloc waveform dataset (use :func:`open_dataset`; a context manager).

    Attributes
    ----------
    path : Path
    file : h5py.File
        The master file (read-only).
    system : OFDMSystem
        Rebuilt from the ``/system`` attributes.
    recipe : str
        The recipe's TOML text.
    seed : int
    name : str
    schema_version : str
    n_realizations, n_snapshots, n_nodes, dim, max_links : int
    ways : int
    scenario, ranging : str
    comm_range_m : float or None
    dt_s : float or None
    """

    def __init__(self, path):
        self.path = Path(path)
        why = v.unreadable_file(self.path)
        if why:
            raise sc.DatasetError(f"dataset {why} (give the master .h5 file of a dataset)")
        damage = sc.master_bytes_problem(self.path)
        if damage:  # never handed to HDF5, which may crash on damaged metadata
            raise sc.DatasetError(
                f"dataset {self.path}: {damage}; a damaged master: `phyloc generate RECIPE -o "
                f"{self.path} --resume` rebuilds it from the shards (import an imported one again)"
            )
        try:
            self.file = h5py.File(self.path, "r")
        except OSError as exc:
            raise sc.DatasetError(
                f"cannot read {self.path} as HDF5 ({exc}); if its generation was interrupted, "
                f"`phyloc generate RECIPE -o {self.path} --resume` rebuilds it"
            ) from None
        try:
            with _master_read(self.path):
                self._load_meta()
        except BaseException:
            self.file.close()
            raise

    def _load_meta(self):
        a = self.file.attrs
        self.schema_version = sc.check_version(a, self.path, sc.MASTER_FORMAT)
        txt = sc._text
        self.recipe = txt(a["recipe"])
        self.name = txt(a["name"])
        self.seed = int(a["seed"])
        self.phyloc_version = txt(a["phyloc_version"])
        self.created_utc = txt(a["created_utc"])
        self.n_realizations = int(a["n_realizations"])
        self.n_snapshots = int(a["n_snapshots"])
        self.n_nodes = int(a["n_nodes"])
        self.dim = int(a["dim"])
        self.max_links = int(a["max_links"])
        self.ways = int(a["ways"])
        self.scenario = txt(a["scenario"])
        self.ranging = txt(a["ranging"])
        cr, dt = float(a["comm_range_m"]), float(a["dt_s"])
        self.comm_range_m = None if math.isnan(cr) else cr
        self.dt_s = None if math.isnan(dt) else dt
        self.shard_size = int(a["shard_size"])
        self.n_shards = int(a["n_shards"])
        g = self.file["system"].attrs
        fields = (
            "n_subcarriers",
            "subcarrier_spacing_hz",
            "carrier_frequency_hz",
            "tx_power_dbm",
            "temperature_k",
            "noise_figure_db",
            "oversampling",
        )
        self.system = OFDMSystem(**{k: g[k].item() for k in fields if k in g})
        sh = self.file["shards"]
        self.shards = {
            "realization_start": sh["realization_start"][:],
            "realization_stop": sh["realization_stop"][:],
            "complete": sh["complete"][:].astype(bool),
            "file": sh["file"].asstr()[:],
            "file_sha256": np.array([x.decode() for x in sh["file_sha256"][:]]),
            "bytes": sh["bytes"][:],
            "n_links": sh["n_links"][:],
            "n_paths": sh["n_paths"][:],
        }
        self._check_shard_table()
        self.array_names = tuple(sc._text(x) for x in sh["array_sha256"].attrs["arrays"])
        seen = set()  # a master from elsewhere names only its own files (each checked once)
        for name in self.shards["file"]:
            if name not in seen:
                seen.add(name)
                self._check_inside(name, "shards/file")
        for dset in self._virtual_datasets():
            plist = dset.id.get_create_plist()  # the sources' file names only (no selections)
            names = {plist.get_virtual_filename(i) for i in range(plist.get_virtual_count())}
            for name in names - seen:
                seen.add(name)
                self._check_inside(name, f"{dset.name} (a virtual dataset's source)")
        outside = sc.outside_references(self.file, allow_virtual=True)
        if outside:
            raise sc.DatasetError(
                f"dataset {self.path}: {outside}; a dataset reads only its own files (refusing it)"
            )
        self._check_declared_sizes()

    def _check_shard_table(self) -> None:
        """Refuse a master whose shard table disagrees with its own attributes (a column of
        another length than ``n_shards``, realization ranges outside ``n_realizations``): a
        damaged master, which ``generate --resume`` rebuilds from the shards."""
        rows = {len(col) for col in self.shards.values()}
        start, stop = self.shards["realization_start"], self.shards["realization_stop"]
        why = None
        if rows != {self.n_shards}:
            why = f"its shard table has {sorted(rows)} rows where n_shards = {self.n_shards}"
        elif self.n_shards and (
            np.any(start < 0) or np.any(stop < start) or np.any(stop > self.n_realizations)
        ):
            why = f"its shard table's realization ranges leave 0..{self.n_realizations}"
        if why:
            raise sc.DatasetError(
                f"dataset {self.path}: {why} (a damaged master; `phyloc generate RECIPE -o "
                f"{self.path} --resume` rebuilds it from the shards)"
            )

    def _check_declared_sizes(self) -> None:
        """Refuse, from the headers, a master whose datasets declare more than reading them
        can afford: one realization of the per-realization arrays, or the master's own
        (non-virtual) datasets, which ``verify`` reads whole to checksum them, beyond this
        machine's memory; or more propagation paths than its links can have
        (:data:`~phyloc.datasets.schema.MAX_PATHS_PER_LINK` each). A dataset from elsewhere
        must not make phyloc allocate terabytes."""
        found: list = []
        self.file.visititems(
            lambda name, obj: found.append((name, obj)) if isinstance(obj, h5py.Dataset) else None
        )
        per_realization, n_paths, whole = 0, 0, 0
        for name, d in found:
            if d.shape is None:
                continue
            if not d.is_virtual:
                whole += math.prod(d.shape) * d.dtype.itemsize
            if name not in self.array_names:
                continue
            spec = sc.spec_of(name)
            if len(d.shape) != len(spec.axes):
                raise sc.DatasetError(
                    f"dataset {self.path}: array {name} has shape {d.shape}, not the axes "
                    f"{', '.join(spec.axes)}; it is not a phyloc dataset (refusing it)"
                )
            if spec.role == "path":
                n_paths = max(n_paths, int(d.shape[0]))
            elif d.shape[0]:
                per_realization += math.prod(d.shape[1:]) * d.dtype.itemsize
        memory = sc.physical_memory()
        max_paths = self.n_realizations * self.n_snapshots * self.max_links * sc.MAX_PATHS_PER_LINK
        what = ""
        if memory and per_realization > memory:
            what = f"{per_realization / 1e9:.3g} GB per realization"
        elif memory and whole > memory:
            what = f"{whole / 1e9:.3g} GB in the master file's own datasets"
        elif n_paths > max_paths:
            what = f"{n_paths} propagation paths, more than {sc.MAX_PATHS_PER_LINK} per link"
        if what:
            if "GB" in what:
                what += f", more than this machine's {memory / 1e9:.3g} GB of memory"
            raise sc.DatasetError(
                f"dataset {self.path}: its arrays declare {what}; refusing it before reading"
            )

    def _virtual_datasets(self):
        out = []

        def visit(_, obj):
            if isinstance(obj, h5py.Dataset) and obj.is_virtual:
                out.append(obj)

        self.file.visititems(visit)
        return out

    def _check_inside(self, name: str, what: str) -> None:
        """Refuse a file the master names outside the dataset's folder: an absolute path, a
        ``..`` component, or a link that resolves elsewhere (a dataset from someone else
        must not make phyloc read files it was not given)."""
        pure = PurePosixPath(str(name).replace("\\", "/"))
        root = self.path.parent.resolve()
        target = (self.path.parent / str(name)).resolve()
        if pure.is_absolute() or ".." in pure.parts or not target.is_relative_to(root):
            raise sc.DatasetError(
                f"dataset {self.path}: {what} names {name!r}, outside the dataset's folder "
                f"{root}; a dataset reads only files beside its master (refusing it)"
            )

    # -- context manager and basics ----------------------------------------------------------
    def close(self) -> None:
        """Close the master file."""
        self.file.close()

    def __enter__(self) -> Dataset:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"<phyloc Dataset {self.path.name!r}: {self.n_realizations} realizations x "
            f"{self.n_snapshots} snapshots, {self.n_nodes} nodes, N = "
            f"{self.system.n_subcarriers}, {self.shards['complete'].sum()}/{self.n_shards} "
            "shards complete>"
        )

    def __len__(self) -> int:
        return self.n_realizations

    def __iter__(self):
        """Iterate over the realizations (:meth:`realization` of each, in order)."""
        for r in range(self.n_realizations):
            yield self.realization(r)

    def __getitem__(self, name: str) -> h5py.Dataset:
        """The lazy ``h5py.Dataset`` of an array, e.g. ``ds["received"]``."""
        if name not in self.array_names:
            raise KeyError(f"no array {name!r}; arrays: {', '.join(self.array_names)}")
        return self.file[name]

    @property
    def arrays(self) -> dict:
        """Every array of the dataset as a lazy ``h5py.Dataset``, by name."""
        return {name: self.file[name] for name in self.array_names}

    @property
    def complete(self) -> bool:
        """Whether every shard is complete."""
        return bool(self.shards["complete"].all())

    @property
    def is_anchor(self) -> h5py.Dataset:
        """``nodes/is_anchor``: [realization, node] uint8."""
        return self.file["nodes/is_anchor"]

    @property
    def positions(self) -> h5py.Dataset:
        """``nodes/positions``: [realization, snapshot, node, dim] float64 [m]."""
        return self.file["nodes/positions"]

    @property
    def received(self) -> h5py.Dataset:
        """``received``: [realization, snapshot, link, sample] complex64 [√W]."""
        return self.file["received"]

    @property
    def symbols(self) -> h5py.Dataset:
        """``symbols``: [realization, node, N] complex64."""
        return self.file["symbols"]

    def load_recipe(self):
        """The stored recipe as a validated :class:`~phyloc.config.Recipe`."""
        from phyloc.config import load_recipe

        return load_recipe(self.recipe)

    # -- availability ---------------------------------------------------------------------------
    def _realization(self, r) -> int:
        r = v.integer("realization", r)
        if not 0 <= r < self.n_realizations:
            raise ValidationError("realization", r, f"must be in [0, {self.n_realizations})")
        j = r // self.shard_size
        if not self.shards["complete"][j]:
            raise sc.DatasetError(
                f"realization {r} of {self.path} is in shard {j}, which is not complete; "
                f"finish the dataset with `phyloc generate RECIPE -o {self.path} --resume`"
            )
        if not (self.path.parent / self.shards["file"][j]).is_file():
            raise sc.DatasetError(
                f"shard file {self.shards['file'][j]} of {self.path} is missing; regenerate it "
                f"with `phyloc generate RECIPE -o {self.path} --resume`"
            )
        return r

    def _snap(self, t) -> int:
        t = v.integer("snapshot", t)
        if not 0 <= t < self.n_snapshots:
            raise ValidationError("snapshot", t, f"must be in [0, {self.n_snapshots})")
        return t

    def available(self, r: int) -> bool:
        """Whether realization ``r`` is stored (its shard is complete and present)."""
        try:
            self._realization(r)
        except sc.DatasetError:
            return False
        return True

    # -- reading --------------------------------------------------------------------------------
    def _paths(self, r: int, t: int, n: int) -> PathSet:
        if n == 0:
            return PathSet(np.zeros(0), np.zeros(0, np.complex128), np.zeros(1, np.int64))
        f = self.file
        base = int(f["channel/paths/base"][r])
        start = f["channel/paths/start"][r, t, :n].astype(np.int64)
        count = f["channel/paths/count"][r, t, :n].astype(np.int64)
        lo, hi = base + start[0], base + start[-1] + count[-1]
        offsets = np.r_[start - start[0], hi - lo]
        return PathSet(f["channel/paths/delays_s"][lo:hi], f["channel/paths/gains"][lo:hi], offsets)

    def snapshot(self, realization: int, snapshot: int = 0) -> Snapshot:
        """Read one (realization, snapshot): positions, links, samples, pilots, channel truth.

        Parameters
        ----------
        realization : int
            0 <= realization < :attr:`n_realizations`.
        snapshot : int
            0 <= snapshot < :attr:`n_snapshots`.

        Returns
        -------
        Snapshot
            ``snap.received`` gives the frequency-domain ``R_n`` and ``snap.tx_index`` the
            transmitter of every link, as :func:`~phyloc.phy.correlation.correlation_tables`
            takes them.

        Raises
        ------
        DatasetError
            The realization's shard is not complete or its file is missing.
        """
        r, t = self._realization(realization), self._snap(snapshot)
        f = self.file
        n = int(f["links/count"][r, t])
        link = slice(0, n)

        def per_link(name):
            return f[name][r, t, link]

        vel = f["nodes/velocities"][r, t] if "nodes/velocities" in self.array_names else None
        return Snapshot(
            realization=r,
            snapshot=t,
            system=self.system,
            positions=f["nodes/positions"][r, t],
            is_anchor=f["nodes/is_anchor"][r].astype(bool),
            links=f["links/pairs"][r, t, link].astype(np.int64),
            samples=f["received"][r, t, link],
            symbols=f["symbols"][r].astype(np.complex128),
            los=per_link("channel/los").astype(bool),
            nlos_bias_s=per_link("channel/nlos_bias_s"),
            distance_m=per_link("channel/distance_m"),
            path_loss_db=per_link("channel/path_loss_db"),
            shadowing_db=per_link("channel/shadowing_db"),
            received_power_w=per_link("channel/received_power_w"),
            snr_db=per_link("channel/snr_db"),
            paths=self._paths(r, t, n),
            ways=self.ways,
            velocities=vel,
        )

    def snapshots(self, realization: int | None = None):
        """Iterate over the snapshots of one realization, or of all realizations in order."""
        reals = range(self.n_realizations) if realization is None else [realization]
        for r in reals:
            for t in range(self.n_snapshots):
                yield self.snapshot(r, t)

    def realization(self, realization: int) -> Realization:
        """Rebuild realization ``r`` as a :class:`~phyloc.datasets.simulate.Realization`
        (network, pilots, links, frequency-domain received symbols, channel draws), the object
        ``phyloc evaluate`` runs on when it simulates in memory.

        ``received`` are :func:`~phyloc.phy.waveform.from_time_domain` of the stored complex64
        samples; two-way channel draws carry the composite paths only (``components`` None).
        """
        r = self._realization(realization)
        f = self.file
        names = self.array_names
        positions = f["nodes/positions"][r]
        if np.isnan(positions).any():
            raise sc.DatasetError(
                f"realization {r} of {self.path} has no ground-truth positions (it was imported "
                "without `positions`); Dataset.realization and phyloc evaluate need them. "
                "Dataset.snapshot reads its waveforms"
            )
        net = Network(
            positions=positions,
            is_anchor=f["nodes/is_anchor"][r].astype(bool),
            comm_range_m=self.comm_range_m,
            velocities=f["nodes/velocities"][r] if "nodes/velocities" in names else None,
            accelerations=(f["nodes/accelerations"][r] if "nodes/accelerations" in names else None),
            dt_s=self.dt_s,
        )
        counts = f["links/count"][r]
        pairs = f["links/pairs"][r]
        per = {
            name: f[f"channel/{name}"][r]
            for name in (
                "los",
                "distance_m",
                "nlos_bias_s",
                "path_loss_db",
                "shadowing_db",
                "shadowing_std_db",
                "received_power_w",
                "delay_spread_s",
                "k_factor_db",
            )
        }
        links, received, channels = [], [], []
        for t in range(self.n_snapshots):
            n = int(counts[t])
            links.append(pairs[t, :n].astype(np.int64))
            received.append(from_time_domain(f["received"][r, t, :n], self.system))
            channels.append(
                ChannelDraw(
                    paths=self._paths(r, t, n),
                    los=per["los"][t, :n].astype(bool),
                    nlos_bias_s=per["nlos_bias_s"][t, :n],
                    path_loss_db=per["path_loss_db"][t, :n],
                    shadowing_db=per["shadowing_db"][t, :n],
                    shadowing_std_db=per["shadowing_std_db"][t, :n],
                    received_power_w=per["received_power_w"][t, :n],
                    delay_spread_s=per["delay_spread_s"][t, :n],
                    k_factor_db=per["k_factor_db"][t, :n],
                    distances_m=per["distance_m"][t, :n],
                    scenario=self.scenario,
                    ranging=self.ranging,
                )
            )
        symbols = f["symbols"][r].astype(np.complex128)
        return Realization(net, symbols, links, received, channels, self.ways)

    def checksums(self) -> dict:
        """SHA-256 of every array as read through the master (C-order bytes), by name: two
        datasets with equal checksums hold the same data."""
        return {name: sc.sha256_h5(self.file[name]) for name in self.array_names}


def open_dataset(path) -> Dataset:
    """Open a phyloc waveform dataset (its master ``.h5`` file) for reading.

    Arrays are read lazily; use as a context manager (``with open(path) as ds: ...``).

    Raises
    ------
    DatasetError
        The file does not exist, is not HDF5 or not a phyloc dataset.
    SchemaVersionError
        The file was written with a newer major schema version.
    """
    return Dataset(path)


def open_xarray(path):
    """The dataset's master file as an :class:`xarray.DataTree` with named dimensions.

    Every array of the master carries HDF5 dimension scales (schema 1.1): ``realization``,
    ``snapshot`` (times [s]), ``node``, ``coordinate``, ``link``, ``end``, ``subcarrier``
    (frequencies relative to the carrier [Hz]), ``sample`` (times [s]), ``path``, ``shard`` and
    ``array``, so ``xarray.open_datatree(path, engine="h5netcdf")`` (and ``open_dataset`` with
    ``group="nodes"`` etc.) give labelled arrays; this function is that call. Arrays are read
    lazily through the master's virtual datasets. Needs the optional extra
    ``phyloc[xarray]`` (xarray and h5netcdf).

    Raises
    ------
    DatasetError
        The file is not a phyloc dataset, or was written before schema 1.1 (no dimension
        scales: ``phyloc generate RECIPE -o NEW.h5`` rewrites it).
    PhylocError
        xarray or h5netcdf is not installed.
    """
    from phyloc.errors import PhylocError

    with open_dataset(path) as ds:
        version = ds.schema_version
        path = ds.path
    if tuple(int(x) for x in version.split(".")[:2]) < (1, 1):
        raise sc.DatasetError(
            f"{path} has schema {version}, without dimension scales (added in 1.1); "
            "regenerate it with this phyloc to open it with xarray"
        )
    try:
        import xarray
    except ImportError:
        raise PhylocError(
            "open_xarray needs xarray and h5netcdf: pip install 'phyloc[xarray]'"
        ) from None
    return xarray.open_datatree(path, engine="h5netcdf", decode_timedelta=False)


#: ``phyloc.datasets.open`` (the name the package exports).
open = open_dataset
