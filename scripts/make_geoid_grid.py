"""Make the EGM96 geoid grid shipped with flightrecon (``flightrecon/geo/data/egm96_15min.npz``).

EGM96 (Lemoine et al. 1998, NASA/TP-1998-206861; NIMA, NASA GSFC and Ohio State University) is
a work of the U.S. Government, in the public domain.  Its geoid heights on a 5' grid are
redistributed as ``egm96-5.pgm`` by GeographicLib and, as a NumPy array, inside the PyPI
package ``egm96`` (0.3.0, MIT; it needs Python 3.12 and NumPy 2.5, so flightrecon, on Python
3.11, cannot depend on it).  This script takes that 5' grid from the package's wheel (fetched
with ``pip download egm96==0.3.0 --no-deps --python-version 3.12 --only-binary=:all:``),
keeps every third node (a 15' grid, 721 x 1440 nodes), and stores it as whole centimetres,
differenced along the longitude then the latitude (int16; 0.7 MB compressed).

Bilinear interpolation of the 15' grid against that of the 5' grid, over 200 000 points
uniform on the sphere: RMS 0.036 m, 99th percentile 0.15 m, largest 0.68 m (a few steep
places); against NGA's published EGM96 test values (spherical harmonics to degree 360) at
six points within 0.06 m (``tests/test_geoid.py``).

Usage::

    python scripts/make_geoid_grid.py egm96-0.3.0-py3-none-any.whl
"""

from __future__ import annotations

import argparse
import io
import zipfile
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "flightrecon" / "geo" / "data" / "egm96_15min.npz"
STEP = 3          # 5' nodes per 15' node


def five_minute_grid_cm(wheel: Path) -> np.ndarray:
    """The 5' grid [cm] (2161 latitudes from -90, 4321 longitudes from -180 to +180) of the
    ``egm96`` wheel, stored there as second differences (latitude then longitude) of cm."""
    with zipfile.ZipFile(wheel) as z, z.open("egm96/data/egm96-5.npz") as f:
        data = np.load(io.BytesIO(f.read()))
        lat, lon, d2 = data["latitudes"], data["longitudes"], data["undulation_d2"]
    assert lat[0] == -90 and lon[0] == -180 and d2.shape == (2161, 4321)
    cm = np.cumsum(d2.astype(np.int32), axis=0)
    return np.cumsum(cm, axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("wheel", type=Path, help="egm96-0.3.0-py3-none-any.whl")
    ap.add_argument("-o", "--out", type=Path, default=OUT)
    args = ap.parse_args()
    cm = five_minute_grid_cm(args.wheel)[::STEP, ::STEP][:, :-1]     # drop +180 (= -180)
    d1 = np.diff(cm, axis=1, prepend=0)
    d2 = np.diff(d1, axis=0, prepend=0)
    assert np.abs(d2).max() < 2**15
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(args.out, n_cm_d2=d2.astype(np.int16),
                        step_deg=np.float64(STEP * 5 / 60), lat0_deg=np.float64(-90.0),
                        lon0_deg=np.float64(-180.0))
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e6:.2f} MB, {cm.shape} nodes, "
          f"{cm.min() / 100:.2f}..{cm.max() / 100:.2f} m)")


if __name__ == "__main__":
    main()
