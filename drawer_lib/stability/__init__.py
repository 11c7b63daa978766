"""The ``stability`` stage: integrators x timesteps x (the twin's parts and the stiff and extreme
cases) against closed forms or a fine reference (``hinge``: the analytic building block,
``study``: the matrix, the choice and the remedies, ``pipeline``: the stage's work)."""
