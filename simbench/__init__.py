"""simbench: a physics-simulation validation testbed for motion-capture skeleton calibration."""

__version__ = "0.1.0"
