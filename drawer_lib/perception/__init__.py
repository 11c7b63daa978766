"""Perception (DRAWER §3.3, segmentation): 2D detections lifted to the mesh, a co-occurrence graph, Louvain candidates, back-projection scores -> segments; a geometric fallback without detections."""
