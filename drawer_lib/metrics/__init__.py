"""Metrics of every stage (DESIGN §6): geometry, images (PSNR / SSIM / LPIPS), articulation, and the evaluate stage."""
