"""drawer_lib: the library behind the DRAWER pipeline (all logic; no CLI code).

Subpackages follow the data flow of the paper: ``io`` (captures, manifests, parts files),
``geometry`` (conventions and pure camera/rotation ops), ``synth`` (procedural kitchens with
ground truth), ``sfm`` (video -> posed frames), ``metrics`` (scoring against ground truth),
``config`` (typed configs and the params.yaml composition), ``runner`` (the stage runner).
"""

__version__ = "0.1.0"
