"""Typed configs at the stage boundary, params.yaml composition, stage helpers."""
