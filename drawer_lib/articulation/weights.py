"""The decision weights file (``drawer.decision_weights/1``, docs/formats.md#decision-weights):
what the ``fit_decisions`` stage writes and ``articulate`` reads when ``articulate.types.weights``
is ``fitted``.

    {"schema": "drawer.decision_weights/1",
     "weights": {"drawer": {"bias": 4.69, "handle": 0.82, ...}, "door": {...}, ...},
     "fit": {...}}          # how they were fitted (lambda, kitchens, fronts per hypothesis, ...)
"""

import json
from pathlib import Path

from drawer_lib.articulation.config import TypesConfig
from drawer_lib.articulation.vocab import check_weights
from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.images import write_json

SCHEMA = "drawer.decision_weights/1"


def write_weights(path: Path, weights: dict[str, dict[str, float]], fit: dict) -> None:
    """Write ``weights`` {set: {feature: weight}} (every weight finite) and the ``fit`` record."""
    check_weights(weights, str(path))
    write_json(Path(path), {"schema": SCHEMA, "weights": weights, "fit": fit})


def read_weights(path: Path) -> dict[str, dict[str, float]]:
    """The weights of a decision weights file; an error naming the file when it is missing or
    malformed."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no decision weights (the fit_decisions stage writes them: "
                         "`dvc repro fit_decisions`; or set articulate.types.weights=prior)")
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: not a decision weights file ({e})") from None
    if not isinstance(d, dict) or d.get("schema") != SCHEMA:
        raise InputError(f"{path}: schema {d.get('schema') if isinstance(d, dict) else None!r}, expected {SCHEMA!r}")
    w = d.get("weights")
    try:
        check_weights(w, str(path))
    except ConfigError as e:
        raise InputError(str(e)) from None
    return {k: {f: float(v) for f, v in ws.items()} for k, ws in w.items()}


def resolve_weights(cfg: TypesConfig, fitted: Path) -> dict[str, dict[str, float]]:
    """The score rule's weights: the file ``fitted`` (``weights: fitted``) or ``cfg.prior``
    (``weights: prior``, or the handle rule, which uses none)."""
    return read_weights(fitted) if cfg.rule == "score" and cfg.weights == "fitted" else cfg.prior
