"""Procedural kitchens: layout, MuJoCo model (MjSpec), rendering, simulated sensors, ground truth."""
