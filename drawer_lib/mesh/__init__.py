"""Meshes from SDF fields: marching cubes where the cameras saw, clean-up, simplification."""
