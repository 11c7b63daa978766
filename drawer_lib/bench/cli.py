"""Command-line pieces the benchmark scripts share (``scripts/bench_detect.py``,
``scripts/bench_decode.py``); no stage imports this module."""

import yaml

from drawer_lib.synth.config import LAYOUT_KEYS


def parse_layout(pairs: list[str]) -> dict:
    """``KEY=VALUE`` pairs (YAML values) as layout keys, checked against the layout block's
    fields; exits with a message naming the bad pair.

    >>> parse_layout(["module_widths=[0.6, 0.9]", "base_modules=6"])
    {'module_widths': [0.6, 0.9], 'base_modules': 6}
    """
    out = {}
    for kv in pairs:
        key, sep, val = kv.partition("=")
        if not sep or key not in LAYOUT_KEYS:
            raise SystemExit(f"error: --layout {kv!r}: not KEY=VALUE with KEY a layout field ({', '.join(sorted(LAYOUT_KEYS))})")
        out[key] = yaml.safe_load(val)
    return out
