"""Articulation (DRAWER §3.3, the part after segmentation): segments + mesh -> ``parts.json``.

``fronts`` (the front rectangle of a planar segment, refined by its masks, shared edges),
``handles`` (protrusions and handle masks, assigned to fronts, stacked pulls), ``joints`` (type
decision, hinge axis, drawer travel from the carcass depth, sliding pairs), ``infer`` (the
built-in estimator composing them), ``estimators`` (the slot for learned ones), ``config``
(every threshold), ``pipeline`` (the ``articulate`` stage's work).
"""
