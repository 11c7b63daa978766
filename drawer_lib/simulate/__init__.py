"""The ``simulate`` stage: every part of the exported twin driven open in MuJoCo (``drive``), the
interaction probes a robot-learning user relies on (``interact``) and the stage's work
(``pipeline``)."""
