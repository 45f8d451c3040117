"""Beams of a satellite in a run: which it lights, how UTs share them, their precoded service."""
