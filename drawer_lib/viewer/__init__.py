"""A browser viewer of a twin folder (docs/formats.md#twin-drawertwin1) built on viser: the static and per-part
Gaussians, collision hulls, joint axes, a slider per joint, live MuJoCo physics, and shareable
recordings. ``python -m drawer_lib.viewer out/<scene>/twin [--port N]``; see docs/viewer.md.

* :mod:`drawer_lib.viewer.scene`: the twin as the viewer draws it (no web code; tested alone);
* :mod:`drawer_lib.viewer.app`: the viser scene, the GUI and the physics thread;
* :mod:`drawer_lib.viewer.record`: the "open every part in turn" recording;
* :mod:`drawer_lib.viewer.browser`: a headless Chromium driven over the DevTools protocol (the
  tests and the load-time benchmark use it).
"""
