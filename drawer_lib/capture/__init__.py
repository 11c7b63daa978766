"""The capture stage: scene and capture configs, the three sources (synth, video, dir)."""
