"""Metrics of every stage (definitions: docs/formats.md#metric-definitions): geometry, images (PSNR / SSIM / LPIPS), articulation, and the evaluate stage."""
