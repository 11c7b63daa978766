"""Simulation export of the twin (``drawer.twin/1``, docs/formats.md): the in-memory description (``model``), MuJoCo
MJCF (``mjcf``), physical checks (``checks``), URDF (``urdf``) and USD (``usd``)."""
