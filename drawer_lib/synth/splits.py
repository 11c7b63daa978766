"""The benchmark splits of procedural kitchens: a ``train`` split that perception is tuned on
and a ``test`` split it never is (other seeds *and* other distributions of sizes, styles and
counts); and ``hand``, eight kitchens written by hand (``layout.modules``), never tuned on. Kitchen ``k``
of a split is a fixed function of ``(split, k)``.

| | train (seeds 100 + k) | test (seeds 500 + k) |
|---|---|---|
| modules | 2-5 base, 1-4 wall (a lone wall cabinet: fronts without neighbours), 0-2 tall, 0-1 fixed fronts | 3-6 base, 2-5 wall, 0-2 tall, 0-2 fixed fronts |
| widths (single / double) | 0.40-0.60 / 0.8-0.9 m | 0.30-0.35, 0.55-0.80 / 0.7, 1.0, 1.1 m |
| carcass (train: uniform per kitchen) | 0.60-0.90 high, 0.50-0.65 deep, 6-15 cm plinth, 16-24 mm fronts, 2-5 mm gaps | 0.78 high, 0.62 deep, 12 cm plinth, 22 mm fronts, 4 mm gaps |
| wall cabinets | 0.30-0.80 high, 0.28-0.40 deep, from 1.40-1.70 m (tops up to 2.5 m) | 0.60 or 0.85 high, 0.35 deep, from 1.50 m |
| tall units | 1.80-2.30 m, 0.50-0.80 wide | 2.10 m, 0.70 or 0.75 wide |
| wall fronts | door, double door (hinged at the outer edges), flaps, sliding pair and single, glass (vitrine) single and double doors | no glass doors |
| handle styles (one per kitchen) | bar, knob, edge, recessed | bar, small_knob, edge, recessed |
| fronts without a handle | 10 % | 15 % |
| appliances | oven, dishwasher (weights 1.2), a microwave in half the kitchens | oven, dishwasher (1.0), a microwave in every kitchen |
| sliding doors (two panels / one on a rail) | weights 1.0 / 1.2; k = 0, 4, .. require one on a rail, k = 2, 6, .. a pair and a flap | 0.8 / 1.0 |
| kitchen yaw | +-40 deg | +-45 deg |
| frames | 200x150 x 48, every 4th kitchen (k = 3, 7, ..) 320x240 x 60 | the same, at k = 1, 5, .. |

The train split is the wide one (heights from a 30 cm wall cabinet to a 2.3 m tall unit, lone
fronts, glass fronts): the weights fitted on it should not carry one generator's habits. The
test split is kept as it was.

Both splits draw every module type (the sliding door without a partner, fridges with one
and two doors, pantry doors, ovens, dishwashers, microwaves); the test split's weights differ.

The ``hand`` split (:data:`HAND`) is not drawn: each kitchen's runs of modules, widths, heights
and handle style were written by hand as a kitchen planner would, in combinations neither split
draws (a galley of 30 cm units; 80 cm drawer banks under lift-up flaps; tall units at both ends;
85 cm carcasses with recessed pulls and push-to-open fronts; a compact studio; doors only; drawer
banks with half the fronts push-to-open; a long run with every kind). Only materials, hinge
sides, objects and the camera's walk come from the seed. ``hand_tune`` (:data:`HAND_TUNE`) is ten
kitchens written the same way to be tuned on, as the train split is for the drawn ones.
"""

import copy

import numpy as np

SPLITS = ("train", "test", "hand", "hand_tune")

# the hand split: {seed, layout, camera} per kitchen (LayoutConfig.modules: [type, width m] left to right)
HAND = [
    {"seed": 900, "layout": {  # a galley of narrow units, edge pulls
        "modules": {"base": [["drawers", 0.3], ["door", 0.3], ["drawers", 0.45], ["oven", 0.6], ["drawer_door", 0.45],
                             ["door", 0.3]],
                    "wall": [["door", 0.3], ["door", 0.3], ["flap_up", 0.6], ["door", 0.45], ["door", 0.45]]},
        "handle_styles": ["edge"], "no_handle_p": 0.0, "fixed_fronts": 0, "microwaves": 0, "yaw_deg": [-15.0, -15.0],
        "carcass_height": 0.8, "base_depth": 0.6, "plinth_height": 0.1, "wall_bottom": 1.45, "wall_height": 0.72,
        "wall_depth": 0.32, "front_gap": 0.003, "front_thickness": 0.019},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 901, "layout": {  # wide drawer banks under lift-up flaps, a fridge, long bars
        "modules": {"base": [["drawers", 0.8], ["drawers", 0.8], ["sink", 1.0], ["dishwasher", 0.6]],
                    "wall": [["flap_up", 0.8], ["flap_up", 0.8], ["double_door", 1.0]],
                    "tall": [["right", "fridge1"]]},
        "handle_styles": ["bar"], "no_handle_p": 0.0, "microwaves": 1, "yaw_deg": [10.0, 10.0],
        "carcass_height": 0.72, "base_depth": 0.6, "plinth_height": 0.15, "wall_bottom": 1.5, "wall_height": 0.4,
        "wall_depth": 0.35, "tall_height": 2.05, "tall_width": 0.6, "front_gap": 0.002, "front_thickness": 0.018},
     "camera": {"n_frames": 60, "width": 320, "height": 240}},
    {"seed": 902, "layout": {  # tall units at both ends, knobs
        "modules": {"base": [["door", 0.5], ["drawers", 0.5], ["double_door", 1.0]],
                    "wall": [["door", 0.5], ["sliding", 1.0], ["door", 0.5]],
                    "tall": [["left", "pantry"], ["right", "fridge2"]]},
        "handle_styles": ["knob"], "no_handle_p": 0.0, "microwaves": 0, "yaw_deg": [0.0, 0.0],
        "carcass_height": 0.76, "base_depth": 0.56, "plinth_height": 0.08, "wall_bottom": 1.55, "wall_height": 0.65,
        "wall_depth": 0.3, "tall_height": 2.2, "tall_width": 0.6, "front_gap": 0.003, "front_thickness": 0.02},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 903, "layout": {  # tall carcasses, recessed pulls, some push-to-open fronts, glass and a lone slider
        "modules": {"base": [["drawer_door", 0.6], ["drawers", 0.4], ["appliance", 0.6], ["double_door", 0.9],
                             ["drawers", 0.6]],
                    "wall": [["sliding_single", 0.9], ["door", 0.4], ["glass_door", 0.6], ["double_door", 0.9]],
                    "tall": [["left", "split"]]},
        "handle_styles": ["recessed"], "no_handle_p": 0.15, "microwaves": 0, "yaw_deg": [-30.0, -30.0],
        "carcass_height": 0.85, "base_depth": 0.62, "plinth_height": 0.1, "wall_bottom": 1.6, "wall_height": 0.7,
        "wall_depth": 0.36, "tall_height": 2.15, "tall_width": 0.6, "front_gap": 0.004, "front_thickness": 0.022},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 904, "layout": {  # a compact studio kitchen: few units, a microwave, small knobs, low wall flap
        "modules": {"base": [["door", 0.45], ["oven", 0.6], ["drawers", 0.45]],
                    "wall": [["flap_down", 0.45], ["door", 0.6]]},
        "handle_styles": ["small_knob"], "no_handle_p": 0.0, "microwaves": 1, "yaw_deg": [25.0, 25.0],
        "carcass_height": 0.7, "base_depth": 0.55, "plinth_height": 0.12, "wall_bottom": 1.4, "wall_height": 0.5,
        "wall_depth": 0.3, "front_gap": 0.003, "front_thickness": 0.019},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 905, "layout": {  # doors only, single and double, long bars
        "modules": {"base": [["double_door", 0.8], ["door", 0.4], ["door", 0.4], ["sink", 0.8], ["door", 0.6]],
                    "wall": [["double_door", 0.8], ["door", 0.4], ["door", 0.4], ["double_door", 0.8]]},
        "handle_styles": ["bar"], "no_handle_p": 0.0, "microwaves": 0, "yaw_deg": [35.0, 35.0],
        "carcass_height": 0.78, "base_depth": 0.6, "plinth_height": 0.1, "wall_bottom": 1.5, "wall_height": 0.8,
        "wall_depth": 0.35, "front_gap": 0.003, "front_thickness": 0.02},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 906, "layout": {  # drawer banks under lift-up flaps, half the fronts push-to-open
        "modules": {"base": [["drawers", 0.6], ["drawers", 0.6], ["drawers", 0.9], ["dishwasher", 0.6]],
                    "wall": [["flap_up", 0.6], ["flap_up", 0.6], ["flap_up", 0.9]]},
        "handle_styles": ["edge"], "no_handle_p": 0.5, "microwaves": 0, "yaw_deg": [-40.0, -40.0],
        "carcass_height": 0.8, "base_depth": 0.6, "plinth_height": 0.1, "wall_bottom": 1.55, "wall_height": 0.45,
        "wall_depth": 0.35, "front_gap": 0.003, "front_thickness": 0.019},
     "camera": {"n_frames": 48, "width": 200, "height": 150}},
    {"seed": 907, "layout": {  # a long run with every kind: sliding pairs and a lone slider, glass, two tall units
        "modules": {"base": [["drawers", 0.6], ["door", 0.4], ["oven", 0.6], ["drawers", 0.3], ["double_door", 1.2],
                             ["drawer_door", 0.5]],
                    "wall": [["sliding", 1.2], ["sliding_single", 0.8], ["door", 0.4], ["glass_double", 0.8]],
                    "tall": [["left", "fridge2"], ["right", "split"]]},
        "handle_styles": ["knob"], "no_handle_p": 0.0, "microwaves": 1, "yaw_deg": [5.0, 5.0],
        "carcass_height": 0.74, "base_depth": 0.58, "plinth_height": 0.1, "wall_bottom": 1.5, "wall_height": 0.7,
        "wall_depth": 0.33, "tall_height": 2.0, "tall_width": 0.65, "front_gap": 0.003, "front_thickness": 0.019},
     "camera": {"n_frames": 60, "width": 320, "height": 240}},
]

_CAM_SMALL = {"n_frames": 48, "width": 200, "height": 150}
_CAM_LARGE = {"n_frames": 60, "width": 320, "height": 240}


def _ht(seed, base, wall, tall=None, cam=None, **layout):
    """A kitchen of the hand_tune split: runs of ``[type, width m]`` (and tall units), the camera
    (small by default), other layout keys over a level kitchen without microwaves or handle-less
    fronts."""
    modules = {"base": base, "wall": wall} | ({"tall": tall} if tall else {})
    return {"seed": seed, "layout": {"modules": modules, "yaw_deg": [0.0, 0.0], "no_handle_p": 0.0, "microwaves": 0,
                                     **layout},
            "camera": dict(cam or _CAM_SMALL)}


# the hand_tune split: kitchens written by hand as the hand split's are, but to be tuned on (a
# planner's catalogue widths and runs: 60 cm grids, pairs of singles where a double would do,
# wide pan drawers, glass and sliding wall fronts); written without reading the hand split's
# module lists
HAND_TUNE = [
    _ht(950, [["drawers", 0.6], ["door", 0.6], ["sink", 0.8], ["dishwasher", 0.6], ["oven", 0.6], ["drawers", 0.8]],
        [["door", 0.6], ["door", 0.6], ["flap_up", 0.8], ["double_door", 0.8], ["door", 0.4]], [["right", "fridge2"]],
        cam=_CAM_LARGE, handle_styles=["bar"], microwaves=1, yaw_deg=[8.0, 8.0], carcass_height=0.80,
        plinth_height=0.08, base_depth=0.60, wall_bottom=1.50, wall_height=0.80, wall_depth=0.37, tall_height=2.20,
        tall_width=0.60, front_gap=0.003, front_thickness=0.018),   # a family kitchen on a 60 cm grid
    _ht(951, [["drawers", 0.9], ["sink", 0.9], ["dishwasher", 0.6], ["drawers", 0.6], ["drawer_door", 0.6]],
        [["flap_up", 0.9], ["flap_up", 0.9], ["door", 0.6]], [["left", "pantry"]],
        handle_styles=["recessed"], no_handle_p=0.2, carcass_height=0.78, plinth_height=0.12, base_depth=0.60,
        wall_bottom=1.45, wall_height=0.60, wall_depth=0.35, tall_height=2.10, tall_width=0.60, front_gap=0.002,
        front_thickness=0.019),                                      # handleless, pan drawers
    _ht(952, [["door", 0.4], ["sink", 0.6], ["oven", 0.6], ["drawer_door", 0.4]],
        [["door", 0.4], ["door", 0.4], ["door", 0.6], ["door", 0.4]],
        handle_styles=["knob"], carcass_height=0.72, plinth_height=0.10, base_depth=0.56, wall_bottom=1.45,
        wall_height=0.70, wall_depth=0.32, front_gap=0.004, front_thickness=0.016),   # a rented flat's 2 m run
    _ht(953, [["double_door", 1.0], ["drawers", 0.5], ["sink", 1.0], ["double_door", 0.8]],
        [["glass_double", 0.8], ["door", 0.5], ["double_door", 1.0], ["door", 0.5]],
        handle_styles=["small_knob"], yaw_deg=[-20.0, -20.0], carcass_height=0.76, plinth_height=0.14,
        base_depth=0.60, wall_bottom=1.55, wall_height=0.75, wall_depth=0.33, front_gap=0.003,
        front_thickness=0.022),                                      # a country kitchen of double doors
    _ht(954, [["drawers", 0.45], ["oven", 0.6], ["drawers", 0.45], ["dishwasher", 0.45], ["sink", 0.6], ["door", 0.45]],
        [["door", 0.45], ["flap_up", 0.6], ["door", 0.45], ["sliding", 1.0]], [["left", "fridge1"], ["right", "split"]],
        cam=_CAM_LARGE, handle_styles=["edge"], microwaves=1, carcass_height=0.72, plinth_height=0.10, base_depth=0.58,
        wall_bottom=1.50, wall_height=0.70, wall_depth=0.33, tall_height=2.05, tall_width=0.60, front_gap=0.002,
        front_thickness=0.019),                                      # tall units at both ends, 45 cm singles
    _ht(955, [["door", 0.4], ["door", 0.4], ["drawers", 0.4], ["drawers", 0.4], ["sink", 0.8], ["door", 0.5],
              ["door", 0.5]],
        [["door", 0.4], ["door", 0.4], ["door", 0.5], ["door", 0.5], ["flap_down", 0.6]],
        handle_styles=["bar"], yaw_deg=[15.0, 15.0], carcass_height=0.80, plinth_height=0.10, base_depth=0.60,
        wall_bottom=1.50, wall_height=0.80, wall_depth=0.35, front_gap=0.003, front_thickness=0.018),
                                                                     # pairs of singles where a double would do
    _ht(956, [["drawers", 1.2], ["sink", 1.0], ["drawer_door", 0.6], ["door", 0.6]],
        [["flap_up", 1.2], ["door", 0.6], ["double_door", 1.0]],
        cam=_CAM_LARGE, handle_styles=["bar"], carcass_height=0.82, plinth_height=0.08, base_depth=0.62,
        wall_bottom=1.55, wall_height=0.60, wall_depth=0.37, front_gap=0.004, front_thickness=0.020),
                                                                     # wide pan drawers and a wide flap
    _ht(957, [["drawer_door", 0.5], ["sink", 0.6], ["oven", 0.6], ["flap_down", 0.45]],
        [["sliding", 1.2], ["sliding_single", 0.6]],
        handle_styles=["edge"], microwaves=1, carcass_height=0.72, plinth_height=0.10, base_depth=0.55,
        wall_bottom=1.40, wall_height=0.50, wall_depth=0.30, front_gap=0.003, front_thickness=0.018),
                                                                     # a studio with sliding wall fronts
    _ht(958, [["drawers", 0.6], ["drawers", 0.6], ["drawers", 0.6], ["dishwasher", 0.6], ["sink", 0.9],
              ["double_door", 0.9]],
        [["door", 0.6], ["door", 0.6], ["flap_up", 0.9], ["glass_door", 0.45], ["glass_door", 0.45]],
        [["right", "fridge2"]], handle_styles=["small_knob"], no_handle_p=0.1, carcass_height=0.86,
        plinth_height=0.15, base_depth=0.62, wall_bottom=1.60, wall_height=0.90, wall_depth=0.35, tall_height=2.25,
        tall_width=0.65, front_gap=0.0025, front_thickness=0.021),   # a bank of drawers, tall carcasses
    _ht(959, [["door", 0.3], ["door", 0.3], ["oven", 0.6], ["drawers", 0.3], ["sink", 0.6], ["door", 0.6]],
        [["door", 0.3], ["door", 0.3], ["door", 0.6], ["flap_up", 0.6]],
        cam=_CAM_LARGE, handle_styles=["knob"], yaw_deg=[-8.0, -8.0], carcass_height=0.72, plinth_height=0.10,
        base_depth=0.58, wall_bottom=1.45, wall_height=0.65, wall_depth=0.32, front_gap=0.003,
        front_thickness=0.018),                                      # 30 cm units beside an oven
]


WRITTEN = {"hand": HAND, "hand_tune": HAND_TUNE}  # the splits written by hand, kitchen by kitchen


def missing_kitchens(split: str, kitchens: list[int]) -> str | None:
    """Why some of ``kitchens`` are not kitchens of ``split`` (a split written by hand has as
    many as :data:`WRITTEN` lists; the procedural ones any index >= 0), or None when all are."""
    written = WRITTEN.get(split)
    if written is not None and kitchens and max(kitchens) >= len(written):
        return f"the {split} split has kitchens 0 .. {len(written) - 1}"
    return None


def split_synth(split: str, k: int) -> dict:
    """The ``synth`` block (a partial :class:`~drawer_lib.synth.config.SynthConfig` as a dict,
    merged over the default kitchen) of kitchen ``k`` of ``split``."""
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r} (known: {SPLITS})")
    if k < 0:
        raise ValueError(f"kitchen index {k} must be >= 0")
    if split in WRITTEN:
        why = missing_kitchens(split, [k])
        if why:
            raise ValueError(f"{why}, not {k}")
        return copy.deepcopy(WRITTEN[split][k])
    g = np.random.default_rng([1000 if split == "train" else 5000, k])
    if split == "train":
        layout = {
            "base_modules": int(g.integers(2, 6)), "wall_modules": int(g.integers(1, 5)),
            "tall_units": int(g.integers(0, 3)), "fixed_fronts": int(g.integers(0, 2)),
            "base_types": {"door": 2.0, "double_door": 1.0, "drawers": 2.0, "drawer_door": 1.5, "flap_down": 0.3,
                           "oven": 1.2, "dishwasher": 1.2},
            "wall_types": {"door": 2.0, "double_door": 1.0, "flap_up": 1.5, "flap_down": 0.3, "sliding": 1.0,
                           "sliding_single": 1.2, "glass_door": 0.6, "glass_double": 0.6},
            "tall_types": {"split": 1.0, "fridge1": 1.0, "fridge2": 1.0, "pantry": 1.0},
            "handle_styles": ["bar", "knob", "edge", "recessed"],
            "no_handle_p": 0.1,
            "microwaves": int(g.integers(0, 2)),
            "yaw_deg": [-40.0, 40.0],
            # every 4th kitchen requires a sliding door without a partner, every other 4th a
            # top-hinged flap and a sliding pair (else they are rare: the wall run drops modules
            # until it fits); odd k require neither, so the wall runs are not mostly sliding doors
            "require_types": ["drawers", "door"] + {0: ["sliding_single"], 2: ["flap_up", "sliding"]}.get(k % 4, []),
        }
        # sizes randomised per kitchen around the default kitchen's (domain randomisation), in
        # ranges that leave most of the test split's values outside
        u = lambda lo, hi: round(float(g.uniform(lo, hi)), 4)  # noqa: E731
        layout |= {"carcass_height": u(0.60, 0.90), "base_depth": u(0.50, 0.65), "plinth_height": u(0.06, 0.15),
                   "wall_bottom": u(1.40, 1.70), "wall_height": u(0.30, 0.80), "wall_depth": u(0.28, 0.40),
                   "tall_height": u(1.80, 2.30), "tall_width": u(0.50, 0.80), "front_thickness": u(0.016, 0.024),
                   "front_gap": u(0.002, 0.005)}
        camera = _CAM_LARGE if k % 4 == 3 else _CAM_SMALL
        return {"seed": 100 + k, "layout": layout, "camera": dict(camera)}
    layout = {
        "base_modules": int(g.integers(3, 7)), "wall_modules": int(g.integers(2, 6)),
        "tall_units": int(g.integers(0, 3)), "fixed_fronts": int(g.integers(0, 3)),
        "module_widths": [0.3, 0.35, 0.55, 0.65, 0.7, 0.8], "double_widths": [0.7, 1.0, 1.1],
        "base_types": {"door": 1.0, "double_door": 1.5, "drawers": 2.5, "drawer_door": 1.0, "flap_down": 0.1,
                       "oven": 1.0, "dishwasher": 1.0},
        "wall_types": {"door": 1.5, "double_door": 1.5, "flap_up": 1.0, "flap_down": 0.5, "sliding": 0.8,
                       "sliding_single": 1.0},
        "tall_types": {"split": 0.5, "fridge1": 1.0, "fridge2": 1.0, "pantry": 1.0},
        "handle_styles": ["bar", "small_knob", "edge", "recessed"],
        "no_handle_p": 0.15,
        "microwaves": 1,
        "yaw_deg": [-45.0, 45.0],
        "base_depth": 0.62, "carcass_height": 0.78, "plinth_height": 0.12,
        "wall_bottom": 1.5, "wall_height": [0.6, 0.85][int(g.integers(2))], "wall_depth": 0.35,
        "tall_height": 2.1, "tall_width": [0.7, 0.75][int(g.integers(2))],
        "front_gap": 0.004, "front_thickness": 0.022,
    }
    camera = _CAM_LARGE if k % 4 == 1 else _CAM_SMALL
    return {"seed": 500 + k, "layout": layout, "camera": dict(camera)}
