"""Geometry (DRAWER §3.1): the neural SDF (multi-resolution grid field, VolSDF rendering, priors, monocular calibration, training), the TSDF baseline, and field.pt files."""
