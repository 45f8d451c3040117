"""Satellite UPA with partially connected hybrid structure, DFT codebook, UT antennas."""

from leolink.antenna.array import (
    HybridArray,
    beam_gain_lin,
    explicit_gain,
    steering_vector,
    ula_gain,
    upa_gain,
)
from leolink.antenna.codebook import (
    Codebook,
    build_codebook,
    dft_lattice,
    find_oversampling,
    footprint_centres,
    oversampling_interval,
)
from leolink.antenna.impairments import (
    MisalignmentStats,
    misalignment_gain_db,
    quantization_loss_db,
)
from leolink.antenna.terminal import (
    Isotropic,
    LeakyWave,
    Metasurface,
    UPATerminal,
)

__all__ = [
    "Codebook",
    "HybridArray",
    "Isotropic",
    "LeakyWave",
    "Metasurface",
    "MisalignmentStats",
    "UPATerminal",
    "beam_gain_lin",
    "build_codebook",
    "dft_lattice",
    "explicit_gain",
    "find_oversampling",
    "footprint_centres",
    "misalignment_gain_db",
    "oversampling_interval",
    "quantization_loss_db",
    "steering_vector",
    "ula_gain",
    "upa_gain",
]
