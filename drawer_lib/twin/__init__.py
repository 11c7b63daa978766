"""The twin: per-body Gaussians, joint motions and opened-state renders (stage ``twin``)."""
