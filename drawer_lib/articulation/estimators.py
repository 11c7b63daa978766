"""The estimator slot: ``articulate.estimator`` names the function that turns segments into
parts. ``geometric`` is built in (:func:`drawer_lib.articulation.infer.infer_parts`), ``vlm``
adds a local vision-language model's answer for each front (:func:`drawer_lib.articulation.vlm.vlm_parts`;
it reads the keywords ``vlm_views`` and ``typer`` as well); 3DOI is a named slot that needs weights this
project cannot fetch; :func:`register_estimator` plugs a real one in."""

from collections.abc import Callable

from drawer_lib.errors import ConfigError
from drawer_lib.io.parts import Part

# fn(mesh, segments, cam_centers, cfg, handle_hits=..., masks_of=..., face_views=..., weights=..., views=...) -> (parts, decisions)
Estimator = Callable[..., tuple[list[Part], list[dict]]]
_REGISTRY: dict[str, Estimator] = {}
SLOTS = {"3doi": "3DOI (SAM-transformer ViT-B, checkpoint_20230515.pth)"}


def register_estimator(name: str, fn: Estimator) -> None:
    """Make ``articulate.estimator: <name>`` call ``fn`` with the arguments of
    :func:`~drawer_lib.articulation.infer.infer_parts`."""
    _REGISTRY[name] = fn


def get_estimator(name: str) -> Estimator:
    if name == "geometric":
        from drawer_lib.articulation.infer import infer_parts

        return infer_parts
    if name == "vlm":
        from drawer_lib.articulation.vlm import vlm_parts

        return vlm_parts
    if name in _REGISTRY:
        return _REGISTRY[name]
    if name in SLOTS:
        raise ConfigError(f"articulate.estimator = {name!r}: {SLOTS[name]} needs weights or a service that are not "
                          "available here; use 'geometric' or register an implementation with "
                          "drawer_lib.articulation.estimators.register_estimator")
    raise ConfigError(f"articulate.estimator = {name!r} is unknown (known: geometric, vlm, {sorted(_REGISTRY) + sorted(SLOTS)})")
