"""The DRAWER paper's own numbers (CVPR 2025), shown next to ours in the reports: their one home.

Every entry names the table it comes from; the values are the paper's row for its full method
unless the key says otherwise.
"""

PAPER = {
    # Table 3 (appearance ablation): test-view PSNR ↑, SSIM ↑, LPIPS ↓ of each appearance variant
    # (our ``appearance_variant`` names).
    "appearance": {"textured_mesh": (19.71, 0.785, 0.323), "static_gs": (25.87, 0.889, 0.276),
                   "movable_gs": (26.49, 0.896, 0.193), "movable_gs_ste": (27.80, 0.912, 0.159)},
    # Table 4 (articulation): precision = 105 correct of 108 predicted, recall = 105 of 125 GT
    # parts, EA-score over the correct revolute parts.
    "articulation": {"precision": 0.972, "recall": 0.840, "ea_score": 0.994},
    # Table 5 (motion): the motion EMD of DRAWER's twins.
    "motion_emd": 1.41e-5,
}
