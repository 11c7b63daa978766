#!/usr/bin/env python
"""Contact sheet of a capture: RGB | depth | mono depth | mono normals | detections | GT instances.

    python scripts/show_capture.py out/kitchen_small/capture -o preview.png --frames 0 12 24 36
"""

import argparse
from pathlib import Path

import numpy as np

from drawer_lib.io.capture import load_capture
from drawer_lib.report.contact_sheet import save_contact_sheet


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("capture", type=Path)
    ap.add_argument("-o", "--out", type=Path, default=Path("capture_preview.png"))
    ap.add_argument("--frames", type=int, nargs="*", help="frame indices (default: 4 spread over the capture)")
    a = ap.parse_args()
    cap = load_capture(a.capture, check_files=False)
    frames = a.frames or np.linspace(0, len(cap.frames) - 1, 4).round().astype(int).tolist()
    save_contact_sheet(cap, frames, a.out)
    print(f"wrote {a.out} ({len(frames)} frames)")


if __name__ == "__main__":
    main()
