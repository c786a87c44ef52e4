"""The HDF5 layout of a phyloc waveform dataset (schema 1.2; documented in datasets/README.md).

A dataset is a *master* file ``OUT.h5`` and a sidecar folder ``OUT.h5.shards/`` of shard files
``shard-00000.h5``, … . Every shard holds the arrays of a contiguous range of realizations
under the same names as the master; the master joins them with HDF5 virtual datasets and keeps
the shard table (which shards are complete, their SHA-256 checksums). This module holds what
writer and reader share: the version, the array registry (:data:`ARRAYS`), names, checksums and
the exceptions.

Checksums are SHA-256 over the C-order bytes of an array as stored (little-endian; complex
values as interleaved real/imaginary pairs), so any tool can recompute them.

References
----------
The HDF Group, *HDF5 User's Guide*, including its virtual datasets (VDS),
https://docs.hdfgroup.org/; the h5py documentation, https://docs.h5py.org/.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from phyloc.errors import PhylocError
from phyloc.reporting import OutputExistsError

#: Version of the layout written by this phyloc, "MAJOR.MINOR". Readers accept files of the
#: same major version (minor versions only add arrays or attributes) and refuse newer majors.
SCHEMA_VERSION = "1.2"  # 1.1: HDF5 dimension scales on every array of the master;
#                          1.2: the master's bytes carry their SHA-256 in a user block
SCHEMA_MAJOR = int(SCHEMA_VERSION.split(".")[0])
#: Root attribute ``format`` of a master file and of a shard file.
MASTER_FORMAT = "phyloc.dataset"
SHARD_FORMAT = "phyloc.dataset.shard"
#: Scheme by which realization ``i`` gets its random stream (stored as a root attribute).
SEED_SCHEME = "numpy.random.SeedSequence(seed).spawn(n_realizations)[i]"


# -- errors ----------------------------------------------------------------------------------
class DatasetError(PhylocError):
    """A dataset file is missing, unreadable, incomplete or not a phyloc dataset."""


class SchemaVersionError(DatasetError):
    """A dataset was written with a newer, incompatible schema version."""


class DatasetMismatchError(DatasetError):
    """An existing output was generated from a different recipe than the one given."""


class DatasetBusyError(DatasetError):
    """Another process is generating the same output."""


class ShardGenerationError(DatasetError):
    """Some shards failed; the completed ones are kept and ``resume`` finishes the rest."""


class DatasetExistsError(OutputExistsError):
    """The output of ``phyloc generate`` exists and ``resume`` was not requested."""

    def __init__(self, path):
        PhylocError.__init__(
            self,
            f"{path} exists (or its shard folder {shard_dir(path)} does); it is never "
            "overwritten. Pass --resume (resume=True) to finish or repair it, or choose another "
            "output path, or delete both to start over",
        )


# -- names -----------------------------------------------------------------------------------
def shard_dir(path) -> Path:
    """The sidecar folder of the shards of master file ``path``: ``path + ".shards"``."""
    p = Path(path)
    return p.with_name(p.name + ".shards")


def shard_name(index: int) -> str:
    """File name of shard ``index`` inside :func:`shard_dir`: ``shard-00000.h5``."""
    return f"shard-{int(index):05d}.h5"


def max_possible_links(n_agents: int, n_anchors: int) -> int:
    """Directed links of a fully meshed network (anchor–anchor pairs are not links)."""
    return n_agents * (n_agents - 1) + 2 * n_agents * n_anchors


# -- the array registry ----------------------------------------------------------------------
@dataclass(frozen=True)
class ArraySpec:
    """One stored array.

    ``axes`` name the dimensions: ``realization`` (R), ``snapshot`` (K), ``node`` (n),
    ``coordinate`` (dim), ``link`` (L, padded to the largest link count), ``end`` (2: receiver,
    transmitter), ``subcarrier`` (N), ``sample`` (os·N), ``path`` (P, all paths concatenated).
    ``role`` is ``"realization"`` (leading realization axis; a shard stores its rows),
    ``"path"`` (ragged; shards' arrays are concatenated) or ``"base"`` (per-realization start
    of the path rows; recomputed by the master).
    """

    name: str
    dtype: str
    axes: tuple
    units: str
    fill: object
    description: str
    role: str = "realization"
    when: str | None = None  # None: always; else the name of a flag (e.g. "velocities")

    def shape(self, dims: dict) -> tuple:
        """Shape for given dimension sizes (keys: the axis names)."""
        return tuple(int(dims[a]) for a in self.axes)

    def annotate(self, dset) -> None:
        """Write the array's ``units``, ``axes`` and ``description`` attributes on ``dset``
        (an ``h5py.Dataset`` of a shard or of the master)."""
        dset.attrs["units"] = self.units
        dset.attrs["axes"] = ",".join(self.axes)
        dset.attrs["description"] = self.description


_PER_LINK = ("realization", "snapshot", "link")

ARRAYS: tuple[ArraySpec, ...] = (
    ArraySpec(
        "nodes/positions",
        "float64",
        ("realization", "snapshot", "node", "coordinate"),
        "m",
        np.nan,
        "true node positions",
    ),
    ArraySpec(
        "nodes/velocities",
        "float64",
        ("realization", "snapshot", "node", "coordinate"),
        "m/s",
        np.nan,
        "true node velocities (CV/CA and waypoint motion only)",
        when="velocities",
    ),
    ArraySpec(
        "nodes/accelerations",
        "float64",
        ("realization", "snapshot", "node", "coordinate"),
        "m/s^2",
        np.nan,
        "true node accelerations (CA motion only)",
        when="accelerations",
    ),
    ArraySpec(
        "nodes/is_anchor",
        "uint8",
        ("realization", "node"),
        "1",
        0,
        "1 for anchors (known positions), 0 for agents",
    ),
    ArraySpec(
        "links/count",
        "int32",
        ("realization", "snapshot"),
        "1",
        0,
        "number of directed links of the snapshot (the first `count` rows are valid)",
    ),
    ArraySpec(
        "links/pairs",
        "int32",
        ("realization", "snapshot", "link", "end"),
        "1",
        -1,
        "directed link (u, v): node u receives from node v; padding -1",
    ),
    ArraySpec("links/valid", "uint8", _PER_LINK, "1", 0, "1 for a real link, 0 for padding"),
    ArraySpec(
        "symbols",
        "complex64",
        ("realization", "node", "subcarrier"),
        "1",
        0,
        "pilot symbols S_n of each node as transmitter; column j is subcarrier n = j - (N-1)/2",
    ),
    ArraySpec(
        "received",
        "complex64",
        (*_PER_LINK, "sample"),
        "sqrt(W)",
        0,
        "received time-domain samples r(iT), i = 0 .. os*N-1, T = 1/(os*N*f_sc)",
    ),
    ArraySpec("channel/los", "uint8", _PER_LINK, "1", 0, "1 for line-of-sight links"),
    ArraySpec("channel/distance_m", "float64", _PER_LINK, "m", np.nan, "true link distance"),
    ArraySpec(
        "channel/nlos_bias_s",
        "float64",
        _PER_LINK,
        "s",
        np.nan,
        "NLOS bias b (0 for LOS; two-way: forward + backward)",
    ),
    ArraySpec(
        "channel/path_loss_db",
        "float64",
        _PER_LINK,
        "dB",
        np.nan,
        "distance-dependent path loss PL (without shadowing)",
    ),
    ArraySpec(
        "channel/shadowing_db",
        "float64",
        _PER_LINK,
        "dB",
        np.nan,
        "shadow fading SF; the link budget uses PL + SF",
    ),
    ArraySpec(
        "channel/shadowing_std_db",
        "float64",
        _PER_LINK,
        "dB",
        np.nan,
        "standard deviation of SF of the link's path-loss segment",
    ),
    ArraySpec(
        "channel/received_power_w",
        "float64",
        _PER_LINK,
        "W",
        np.nan,
        "received power P_tx - PL - SF = sum over paths of |alpha_l|^2",
    ),
    ArraySpec(
        "channel/snr_db",
        "float64",
        _PER_LINK,
        "dB",
        np.nan,
        "per-sample SNR, received power / noise power sigma^2 (post-correlation: +10 log10 N)",
    ),
    ArraySpec(
        "channel/delay_spread_s",
        "float64",
        _PER_LINK,
        "s",
        np.nan,
        "large-scale delay spread drawn for the link (WINNER II step 4)",
    ),
    ArraySpec(
        "channel/k_factor_db",
        "float64",
        _PER_LINK,
        "dB",
        np.nan,
        "Ricean K-factor of LOS links (NaN for NLOS, +inf for AWGN)",
    ),
    ArraySpec(
        "channel/paths/start",
        "int64",
        _PER_LINK,
        "1",
        0,
        "first row of the link's paths, relative to channel/paths/base of the realization",
    ),
    ArraySpec("channel/paths/count", "int32", _PER_LINK, "1", 0, "number of paths of the link"),
    ArraySpec(
        "channel/paths/base",
        "int64",
        ("realization",),
        "1",
        -1,
        "first row of the realization's paths in channel/paths/delays_s and gains "
        "(-1: realization not available)",
        role="base",
    ),
    ArraySpec(
        "channel/paths/delays_s",
        "float64",
        ("path",),
        "s",
        np.nan,
        "absolute path delays tau_l (two-way: round trip)",
        role="path",
    ),
    ArraySpec(
        "channel/paths/gains",
        "complex128",
        ("path",),
        "sqrt(W)",
        0,
        "complex path gains alpha_l; |alpha_l|^2 is the received power of the path",
        role="path",
    ),
)

ARRAY_NAMES = tuple(a.name for a in ARRAYS)


def arrays_for(flags: dict) -> tuple[ArraySpec, ...]:
    """The arrays stored for a dataset with these optional flags (e.g. ``velocities``)."""
    return tuple(a for a in ARRAYS if a.when is None or flags.get(a.when, False))


def spec_of(name: str) -> ArraySpec:
    """The :class:`ArraySpec` of an array name."""
    for a in ARRAYS:
        if a.name == name:
            return a
    raise KeyError(name)


# -- checksums -------------------------------------------------------------------------------
def sha256_array(a: np.ndarray) -> str:
    """SHA-256 (hex) of the C-order bytes of an in-memory array."""
    return hashlib.sha256(np.ascontiguousarray(a).data).hexdigest()


def sha256_h5(dset, *, max_bytes: int = 1 << 26) -> str:
    """SHA-256 (hex) of an HDF5 dataset's C-order bytes, read in slabs along axis 0 (so equal
    to :func:`sha256_array` of the whole array without holding it in memory)."""
    h = hashlib.sha256()
    if dset.shape is None or dset.size == 0:
        return h.hexdigest()
    if dset.ndim == 0:
        h.update(np.ascontiguousarray(dset[()]).data)
        return h.hexdigest()
    row = max(1, dset.size // dset.shape[0]) * dset.dtype.itemsize
    step = max(1, max_bytes // row)
    for i in range(0, dset.shape[0], step):
        h.update(np.ascontiguousarray(dset[i : i + step]).data)
    return h.hexdigest()


MASTER_HEADER_BYTES = 512
"""Size of the master's HDF5 user block (schema >= 1.2), which holds the bytes' SHA-256."""
MASTER_HEADER_MAGIC = b"phyloc.dataset master sha256="
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def stamp_master(image: bytes) -> bytes:
    """A master file's bytes from its HDF5 image: a user block of
    :data:`MASTER_HEADER_BYTES` holding the SHA-256 of the image, then the image.

    HDF5 skips a user block (it finds its signature at byte 512), so every HDF5 tool reads
    the file as before; phyloc checks the bytes against the digest before it hands the file
    to HDF5, which may crash on damaged metadata instead of raising an error.

    >>> stamped = stamp_master(HDF5_SIGNATURE + bytes(8))
    >>> len(stamped), stamped[:29].decode()
    (528, 'phyloc.dataset master sha256=')
    """
    return stamp_header(hashlib.sha256(image).hexdigest()) + image


def master_bytes_problem(path) -> str | None:
    """What is wrong with a master file's bytes, or None: a header that is not phyloc's, or
    bytes that differ from the SHA-256 in its header (:func:`stamp_master`). A file that
    starts with the HDF5 signature has no header (schema < 1.2, or written by another tool)
    and is left to HDF5 and :func:`master_digest`."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        head = fh.read(MASTER_HEADER_BYTES)
        if head.startswith(HDF5_SIGNATURE):
            return None
        if not head.startswith(MASTER_HEADER_MAGIC) or len(head) < MASTER_HEADER_BYTES:
            return "its first bytes are neither phyloc's header nor an HDF5 signature"
        while block := fh.read(1 << 20):
            h.update(block)
    if head != stamp_header(h.hexdigest()):  # the digest and the zero padding
        return "its bytes differ from the SHA-256 in its header (altered or corrupt)"
    return None


def stamp_header(hexdigest: str) -> bytes:
    """The master's user block for an image of SHA-256 ``hexdigest``."""
    return (MASTER_HEADER_MAGIC + hexdigest.encode() + b"\n").ljust(MASTER_HEADER_BYTES, b"\0")


MASTER_DIGEST_ATTR = "content_sha256"
"""Root attribute of a master file (schema >= 1.1): :func:`master_digest` of its content."""

#: Attributes kept out of the digest: the digest itself and the dimension-scale bookkeeping
#: (object references, rebuilt by HDF5 from the scales that are hashed).
_UNHASHED_ATTRS = frozenset({MASTER_DIGEST_ATTR, "DIMENSION_LIST", "REFERENCE_LIST"})


def _canonical(value) -> bytes:
    a = np.asarray(value)
    if a.dtype.kind in "OSUV":
        return repr(a.tolist()).encode()
    return a.dtype.str.encode() + repr(a.shape).encode() + np.ascontiguousarray(a).tobytes()


def master_digest(f) -> str:
    """SHA-256 of everything a master file holds itself: every group and dataset name, every
    attribute (but the digest and the dimension-scale references), the data of its real
    datasets (shard table, path bases, dimension scales) and, for each virtual dataset, its
    shape, type and mapping (shard file, dataset, selections). A flipped byte in the master's
    arrays or attributes, or a deleted group or attribute, changes it.

    ``f`` is an open ``h5py.File``.
    """
    import h5py

    h = hashlib.sha256()

    def attrs(obj):
        for key in sorted(obj.attrs):
            if key not in _UNHASHED_ATTRS:
                h.update(key.encode() + b"\0" + _canonical(obj.attrs[key]))

    names = []
    f.visit(names.append)
    attrs(f)
    for name in sorted(names):
        obj = f[name]
        h.update(b"\1" + name.encode())
        attrs(obj)
        if not isinstance(obj, h5py.Dataset):
            continue
        h.update(obj.dtype.str.encode() + repr(obj.shape).encode())
        if obj.is_virtual:
            for vs in obj.virtual_sources():
                bounds = vs.vspace.get_select_bounds() if obj.shape else ()
                h.update(repr((vs.file_name, vs.dset_name, bounds)).encode())
        elif obj.dtype.kind == "O":
            h.update(_canonical(obj.asstr()[...]))
        else:
            h.update(_canonical(obj[...]))
    return h.hexdigest()


def sha256_file(path, *, block: int = 1 << 22) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(block):
            h.update(chunk)
    return h.hexdigest()


# -- versions --------------------------------------------------------------------------------
def _text(x) -> str:
    return x.decode() if isinstance(x, bytes) else str(x)


def check_version(attrs, path, expected_format: str) -> str:
    """Check a file's ``format`` and ``schema_version`` attributes; return the version.

    Raises
    ------
    DatasetError
        Not a phyloc dataset (or shard).
    SchemaVersionError
        The major version is newer than this phyloc reads.
    """
    fmt = _text(attrs.get("format", ""))
    if fmt != expected_format:
        what = "dataset master file" if expected_format == MASTER_FORMAT else "dataset shard"
        raise DatasetError(
            f"{path} is not a phyloc {what} (root attribute format = {fmt!r}, expected "
            f"{expected_format!r})"
        )
    version = _text(attrs.get("schema_version", ""))
    try:
        major = int(version.split(".")[0])
    except ValueError:
        raise DatasetError(f"{path} has an unreadable schema_version {version!r}") from None
    if major > SCHEMA_MAJOR:
        from phyloc import __version__

        raise SchemaVersionError(
            f"{path} was written with dataset schema {version}, newer than this phyloc "
            f"({__version__}) can read (schema {SCHEMA_MAJOR}.x); upgrade phyloc to read it"
        )
    return version


# -- shard checks (shared by resume and verify) ------------------------------------------------
def outside_references(f, *, allow_virtual: bool) -> str | None:
    """What in the open HDF5 file ``f`` would make a reader open *another* file, or None: an
    external link, a dataset whose raw data lives in an external file, or (unless
    ``allow_virtual``, as in a master, whose sources are checked by name) a virtual dataset.

    A dataset from someone else must not make phyloc read files it was not given; HDF5
    follows all three silently.
    """
    import h5py

    found = []

    def link(name, lk):
        if isinstance(lk, h5py.ExternalLink):
            found.append(f"{name} is an external link to {lk.filename!r}")
            return True
        return None

    def obj(name, o):
        if isinstance(o, h5py.Dataset):
            if o.is_virtual and not allow_virtual:
                found.append(f"{name} is a virtual dataset (a shard holds its own data)")
                return True
            if not o.is_virtual and o.id.get_create_plist().get_external_count() > 0:
                found.append(f"{name} keeps its data in an external file")
                return True
        return None

    f.visititems_links(link)
    if not found:
        f.visititems(obj)
    return found[0] if found else None


def check_shard(
    path,
    *,
    index: int,
    start: int,
    stop: int,
    fingerprint: str,
    arrays,
    file_sha256: str | None = None,
    dims: dict | None = None,
):
    """Check a shard file completely: file checksum, format, identity, every array's declared
    shape and every array's SHA-256.

    Parameters
    ----------
    path : path of the shard file
    index, start, stop : int
        Expected shard index and realization range ``[start, stop)``.
    fingerprint : str
        Expected ``recipe_fingerprint`` attribute.
    arrays : sequence of ArraySpec
        The arrays the shard must hold.
    file_sha256 : str, optional
        The file checksum recorded by the master (checked when given).
    dims : dict, optional
        The dataset's axis sizes (:meth:`ArraySpec.shape`; ``realization`` is taken from
        ``start``/``stop``): ``link`` and ``path`` are upper bounds, every other axis must
        match. Checked from the arrays' headers before any data is read, so a shard that
        declares an absurd shape (terabytes of fill values) is refused instead of read.

    Returns
    -------
    (record, kind, reason)
        ``record`` (a dict, see :func:`shard_record`) when the shard is sound, else None;
        ``kind`` is None, ``"missing"``, ``"corrupt"`` or ``"foreign"`` (a shard of another
        recipe); ``reason`` says why in words.
    """
    import h5py

    path = Path(path)
    if not path.is_file():
        return None, "missing", f"{path.name} does not exist"
    try:
        digest = sha256_file(path)
        if file_sha256 and digest != file_sha256:
            return None, "corrupt", "file SHA-256 differs from the master's record"
        with h5py.File(path, "r") as f:
            outside = outside_references(f, allow_virtual=False)
            if outside:
                return None, "corrupt", f"refused: {outside}"
            try:
                check_version(f.attrs, path, SHARD_FORMAT)
            except SchemaVersionError:
                raise
            except DatasetError as exc:
                return None, "corrupt", str(exc)
            if _text(f.attrs.get("recipe_fingerprint", "")) != fingerprint:
                return None, "foreign", f"{path.name} was generated from a different recipe"
            got = tuple(
                int(f.attrs.get(k, -1))
                for k in ("shard_index", "realization_start", "realization_stop")
            )
            if got != (index, start, stop):
                return (
                    None,
                    "corrupt",
                    (f"holds shard/realizations {got}, expected {(index, start, stop)}"),
                )
            if int(f.attrs.get("complete", 0)) != 1:
                return None, "corrupt", "not marked complete"
            for a in arrays:
                if a.name not in f:
                    return None, "corrupt", f"array {a.name} is missing"
                d = f[a.name]
                if not isinstance(d, h5py.Dataset) or d.shape is None or not d.shape:
                    return None, "corrupt", f"{a.name} is not an array"
                if a.role != "path" and d.shape[0] != stop - start:
                    return None, "corrupt", f"array {a.name} has shape {d.shape}"
                bad = _shape_outside(a, d.shape, dims, stop - start)
                if bad:
                    return None, "corrupt", bad
            for a in arrays:  # every header sound: now the data
                d = f[a.name]
                stored = _text(d.attrs.get("sha256", ""))
                if sha256_h5(d) != stored:
                    return None, "corrupt", f"SHA-256 of {a.name} does not match its data"
            record = shard_record(f, path, arrays)
            record["file_sha256"] = digest
            return record, None, ""
    except SchemaVersionError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        return None, "corrupt", f"unreadable ({type(exc).__name__}: {exc})"


def physical_memory() -> int:
    """This machine's physical memory [B] (0 where it cannot be read)."""
    import os

    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 0


#: Upper bound on the propagation paths of one link, for a shard whose path count is not
#: known in advance (a resume): far above any channel model's (tens to a few hundred).
MAX_PATHS_PER_LINK = 10_000


def _shape_outside(a: ArraySpec, shape: tuple, dims: dict | None, n_rows: int) -> str:
    """Why ``shape`` (an array's declared shape in a shard of ``n_rows`` realizations) is not
    one the dataset's axis sizes ``dims`` allow (``link`` and ``path`` as upper bounds), or
    ""."""
    if dims is None:
        return ""
    want = tuple(n_rows if ax == "realization" else int(dims[ax]) for ax in a.axes)
    ok = len(shape) == len(want) and all(
        (g <= w) if ax in ("link", "path") else (g == w)
        for g, w, ax in zip(shape, want, a.axes, strict=True)
    )
    if ok:
        return ""
    return (
        f"array {a.name} declares shape {tuple(shape)}, outside this dataset's "
        f"{want} ({', '.join(a.axes)}; link and path counts at most): refused before reading"
    )


def shard_record(f, path, arrays) -> dict:
    """The shard-table row of an open shard file (checksums as stored in its attributes)."""
    path = Path(path)
    return {
        "index": int(f.attrs["shard_index"]),
        "start": int(f.attrs["realization_start"]),
        "stop": int(f.attrs["realization_stop"]),
        "file": path.name,
        "file_sha256": "",
        "bytes": path.stat().st_size,
        "max_links": int(f.attrs["max_links"]),
        "n_links": int(f.attrs["n_links"]),
        "n_paths": int(f.attrs["n_paths"]),
        "path_base": [int(x) for x in f["channel/paths/base"][:]],
        "arrays": {a.name: _text(f[a.name].attrs["sha256"]) for a in arrays},
    }
