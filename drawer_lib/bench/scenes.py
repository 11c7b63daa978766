"""Kitchen ``k`` of a benchmark split as a scene config (what the benchmark's stages, the
built-in detector's fit and the benchmark scripts build)."""

import copy

from drawer_lib.capture.config import SceneConfig
from drawer_lib.config.typed import to_typed
from drawer_lib.errors import ConfigError
from drawer_lib.synth.splits import split_synth


def kitchen_scene(base: dict, split: str, k: int, camera: dict | None = None, layout: dict | None = None
                  ) -> SceneConfig:
    """The scene of kitchen ``k`` of ``split``: the synth scene ``base`` (a scene file's tree)
    with the split's values (:func:`~drawer_lib.synth.splits.split_synth`) merged over it, and
    ``camera`` (keys of the camera block, ``bench.camera``) and ``layout`` (keys of the layout
    block, ``detector.layout``) over those."""
    d = copy.deepcopy(base)
    if d.get("source", "synth") != "synth" or not isinstance(d.get("synth"), dict):
        raise ConfigError(f"bench.base_scene: a synth scene with a synth block is needed, got source {d.get('source')!r}")
    values = split_synth(split, k)
    values["camera"].update(camera or {})
    values["layout"].update(layout or {})
    for key, val in values.items():
        if isinstance(val, dict):
            d["synth"].setdefault(key, {}).update(val)
        else:
            d["synth"][key] = val
    return to_typed(SceneConfig, d, f"bench {split} kitchen {k}", strict=False)
