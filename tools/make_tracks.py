"""Write the example recorded tracks ``ship.csv`` and ``car.csv`` (deterministic, no RNG).

Run from anywhere: ``python tools/make_tracks.py`` (it writes into
``src/leolink/examples/tracks/``, the packaged examples). The tracks are
synthetic: dead reckoning along great circles with a slowly turning heading, using
``leolink.geometry.destination_point`` on the spherical Earth.

- ``ship.csv``: one track (no ``ut`` column), a ship leaving the Strait of Gibraltar
  westwards at 10 m/s (about 19 kn), a fix every 60 s, 40 fixes, at sea level.
- ``car.csv``: one track with a ``ut`` column (``car``), a car near Madrid at 30 m/s
  (108 km/h), a fix every 10 s, 40 fixes, height rising from 650 m to 689 m.
"""

from pathlib import Path

import numpy as np

from leolink.geometry import destination_point

HERE = Path(__file__).resolve().parents[1] / "src" / "leolink" / "examples" / "tracks"


def dead_reckon(lat_deg, lon_deg, heading_deg, speed_m_s, step_s, n_fix):
    """Fixes (time_s, lat_deg, lon_deg) of a mover whose heading follows ``heading_deg[k]``."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    rows = [(0.0, lat, lon)]
    for k in range(1, n_fix):
        lat, lon = destination_point(lat, lon, np.radians(heading_deg[k - 1]), speed_m_s * step_s)
        rows.append((k * step_s, float(lat), float(lon)))
    t, la, lo = np.array(rows).T
    return t, np.degrees(la), np.degrees(lo)


def write(path, header, columns, comment):
    """CSV with ``#`` comment lines and a header."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"# {comment}\n# made by make_tracks.py; units: s, deg, deg, m\n")
        f.write(",".join(header) + "\n")
        for row in zip(*columns, strict=True):
            f.write(",".join(v if isinstance(v, str) else f"{v:.7f}" for v in row) + "\n")


def main():
    n = 40
    k = np.arange(n)
    ship_heading = 260.0 + 15.0 * np.sin(2 * np.pi * k / n)  # gentle S-curve westwards
    t, lat, lon = dead_reckon(35.95, -5.60, ship_heading, 10.0, 60.0, n)
    write(
        HERE / "ship.csv",
        ["time_s", "lat_deg", "lon_deg", "alt_m"],
        [t, lat, lon, np.zeros(n)],
        "example ship track, 10 m/s, fix every 60 s",
    )

    car_heading = 45.0 + 30.0 * np.sin(2 * np.pi * k / 20)  # winding road north-east
    t, lat, lon = dead_reckon(40.40, -3.70, car_heading, 30.0, 10.0, n)
    write(
        HERE / "car.csv",
        ["time_s", "ut", "lat_deg", "lon_deg", "alt_m"],
        [t, ["car"] * n, lat, lon, 650.0 + 1.0 * k],
        "example car track, 30 m/s, fix every 10 s",
    )


if __name__ == "__main__":
    main()
