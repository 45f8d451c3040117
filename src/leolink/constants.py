"""Physical constants, SI units (the unit is in the name)."""

import math

SPEED_OF_LIGHT_M_S = 299_792_458.0
BOLTZMANN_J_K = 1.380649e-23
# 10 log10(k) = -228.599 dBW/K/Hz; the paper rounds it to -228.6 (see docs/errata.md).
BOLTZMANN_DBW_K_HZ = 10.0 * math.log10(BOLTZMANN_J_K)

# Spherical Earth used by the paper and by default everywhere.
EARTH_RADIUS_M = 6_371_000.0
GM_EARTH_M3_S2 = 3.986004418e14
# Sidereal rotation rate (IERS), used when Earth rotation is switched on.
EARTH_ROTATION_RAD_S = 7.2921150e-5

# WGS-84, only where TLEs are used.
WGS84_A_M = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
