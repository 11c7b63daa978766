"""Appearance (DRAWER §3.2): a CPU 3D Gaussian rasterizer (numba kernels with PyTorch references), mesh-anchored Gaussians, their density strategy, training, PLY export."""
