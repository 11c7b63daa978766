"""Simulation export of the twin (DESIGN §5b): the in-memory description (``model``), MuJoCo
MJCF (``mjcf``), physical checks (``checks``), URDF (``urdf``) and USD (``usd``)."""
