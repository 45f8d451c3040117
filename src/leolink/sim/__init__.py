"""Simulation layer: SimPy processes, mobility, beam controller and output writers."""
