"""2D detections and monocular priors as method components (the ``detect``, ``priors`` and
``detector`` stages).

``config`` (the ``detect``, ``priors`` and ``detector`` config groups), ``masks`` (instance masks
to the capture format's label maps), ``hub`` (foundation models' weights: a local folder or the
Hugging Face cache, never fetched unless allowed), ``foundation`` (OWLv2 + SAM detections, Depth
Anything depth and the normals read off it, through ``transformers``), ``builtin`` (the
built-in detector: a small fully convolutional network and its instance decoding), ``data`` and
``train`` (its training views rendered from the benchmark's train split, and its fit),
``pipeline`` (the stages' work: a model's outputs written as an overlay of the capture,
:mod:`drawer_lib.io.overlay`).
"""
