"""Build src/leolink/data/coastlines_50m.npz from the world-atlas npm package (Natural Earth).

Usage (one-off, offline once the tarball is on disk; leolink never downloads at run time)::

    npm pack world-atlas@2.0.2            # -> world-atlas-2.0.2.tgz
    python tools/make_coastlines.py world-atlas-2.0.2.tgz

The package's ``land-50m.json`` is Natural Earth 4.1.0 1:50m land (public domain) as a
quantized TopoJSON topology. Every arc of the ``land`` object is a piece of coastline, so
the arcs are decoded (delta-decoded, then the quantization transform applied) and stored
as polylines: ``lon_deg`` and ``lat_deg`` (float32) with NaN between arcs, plus ``starts``
(int64 index of each arc's first point). The rings are not re-assembled: a map draws lines.
"""

from __future__ import annotations

import json
import sys
import tarfile
from pathlib import Path

import numpy as np

MEMBER = "package/land-50m.json"
OUT = Path(__file__).resolve().parents[1] / "src" / "leolink" / "data" / "coastlines_50m.npz"


def decode_arcs(topology):
    """Arcs of a quantized TopoJSON topology as a list of (n, 2) [lon, lat] float64 arrays."""
    scale = np.asarray(topology["transform"]["scale"], float)
    translate = np.asarray(topology["transform"]["translate"], float)
    # TopoJSON spec 2.1.3: quantized positions are delta-encoded; x = x_q * scale + translate.
    return [
        np.cumsum(np.asarray(arc, float), axis=0) * scale + translate for arc in topology["arcs"]
    ]


def main(tgz):
    with tarfile.open(tgz) as tar:
        topology = json.load(tar.extractfile(MEMBER))
    arcs = decode_arcs(topology)
    starts, pieces, offset = [], [], 0
    for arc in arcs:  # one-off build script: a loop over ~1,400 arcs is fine
        starts.append(offset)
        pieces.append(np.vstack([arc, [np.nan, np.nan]]))
        offset += arc.shape[0] + 1
    lonlat = np.vstack(pieces).astype(np.float32)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        OUT, lon_deg=lonlat[:, 0], lat_deg=lonlat[:, 1], starts=np.asarray(starts, np.int64)
    )
    print(f"{OUT}: {len(arcs)} arcs, {lonlat.shape[0]} points, {OUT.stat().st_size} bytes")


if __name__ == "__main__":
    main(sys.argv[1])
