"""Print the on-disk layout of a tiny phyloc dataset, in the style of ``h5dump -H``.

The documentation build runs this script (``docs/conf.py``) and includes its output on the
"Datasets" page, so the layout shown there is the one the installed phyloc writes. Run it by
hand with ``python docs/examples/dataset_layout.py``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

import phyloc.datasets as pds

#: A dataset recipe small enough to write in about a second: 3 agents and 1 anchor in AWGN,
#: 2 realizations of 2 snapshots (one shard each), 33 subcarriers.
RECIPE = """
kind = "dataset"
name = "layout_example"
seed = 1
description = "3 agents, 1 anchor, AWGN, 2 realizations of 2 snapshots"

[system]
n_subcarriers = 33

[network]
n_agents = 3
anchors = 1
dim = 2
region_m = [50.0, 50.0]

[network.motion]
model = "random_walk"
n_snapshots = 2
dt_s = 1.0

[channel]
scenario = "awgn"

[dataset]
realizations = 2
shard_size = 1
"""


def _dtype(d: np.dtype) -> str:
    if d.kind == "c":
        return f'compound {{"r", "i"}} of float{d.itemsize * 4}'
    if d.kind in "SO" or h5py.check_string_dtype(d) is not None:
        return "string"
    return str(d)


def _attrs(obj, indent: str, out: list[str], skip=("sha256",)) -> None:
    for key in sorted(obj.attrs):
        if key in skip:
            continue
        value = obj.attrs[key]
        if isinstance(value, bytes):
            value = value.decode()
        if isinstance(value, np.generic):
            value = value.item()
        text = repr(value) if not isinstance(value, str) else f'"{value}"'
        if len(text) > 60:
            text = text[:57] + '..."'
        out.append(f"{indent}ATTRIBUTE {key} = {text}")


def layout(path, *, root_attrs: bool = True) -> str:
    """``h5dump -H``-style listing of an HDF5 file: groups, datasets (dtype, shape), attributes.

    Parameters
    ----------
    path : str or Path
        The HDF5 file.
    root_attrs : bool
        List the root attributes too.

    Returns
    -------
    text : str
        One line per group, dataset and attribute, indented by nesting level.
    """
    out: list[str] = []
    with h5py.File(path, "r") as f:
        out.append(f'HDF5 "{Path(path).name}" {{')
        out.append('GROUP "/" {')
        if root_attrs:
            _attrs(f, "   ", out, skip=("recipe", "sha256"))

        def visit(group, indent):
            for name in sorted(group):
                obj = group[name]
                if isinstance(obj, h5py.Group):
                    out.append(f'{indent}GROUP "{name}" {{')
                    _attrs(obj, indent + "   ", out)
                    visit(obj, indent + "   ")
                    out.append(f"{indent}}}")
                else:
                    kind = "VIRTUAL " if obj.is_virtual else ""
                    dims = ", ".join(map(str, obj.shape))
                    shape = "SCALAR" if obj.shape == () else f"( {dims} )"
                    out.append(f'{indent}DATASET "{name}" {{ {kind}{_dtype(obj.dtype)} {shape} }}')
                    for key in ("units", "axes"):
                        if key in obj.attrs:
                            out.append(f'{indent}   ATTRIBUTE {key} = "{obj.attrs[key]}"')

        visit(f, "   ")
        out.append("}")
        out.append("}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Write the example dataset into a temporary folder and print its master file's layout."""
    del argv
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "example.h5"
        pds.generate(RECIPE, out, progress=False)
        print(layout(out))
        shards = sorted((Path(tmp) / "example.h5.shards").glob("shard-*.h5"))
        print()
        print(f"example.h5.shards/: {', '.join(p.name for p in shards)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
