"""The twin's simulation exports (``drawer.twin/1``, docs/formats.md): MuJoCo MJCF (``mjcf``), URDF
(``urdf``) and USD (``usd``) built from the body model (:mod:`drawer_lib.bodies`), their physical
checks (``checks``) and their config (``config``, the ``sim`` group). The stages that run the
exported twin live in :mod:`drawer_lib.simulate` and :mod:`drawer_lib.stability`."""
