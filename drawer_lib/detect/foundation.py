"""The paper's foundation models through Hugging Face ``transformers``: open-vocabulary boxes
(OWLv2) segmented by SAM for the detections, Depth Anything for relative depth (normals read
off it). Weights come from a local folder or the Hugging Face cache (:mod:`drawer_lib.hub`).

Each model runs one frame at a time on ``device`` in inference mode; nothing is kept between
frames but the model.
"""

import numpy as np
import torch
import torch.nn.functional as F

from drawer_lib.detect.config import DetectConfig, PriorsConfig
from drawer_lib.devices import torch_device
from drawer_lib.hub import model_dir
from drawer_lib.detect.masks import Detection
from drawer_lib.errors import NonFiniteError
from drawer_lib.geometry.camera import Intrinsics, normals_from_depth


def box_nms(boxes: np.ndarray, scores: np.ndarray, iou: float) -> list[int]:
    """Greedy non-maximum suppression: indices of the boxes [N, 4] (x0, y0, x1, y1) kept, best
    score first; a box overlapping a kept one by more than ``iou`` is dropped.

    >>> box_nms(np.array([[0, 0, 10, 10], [1, 1, 10, 10], [20, 20, 30, 30.]]), np.array([.9, .8, .7]), 0.5)
    [0, 2]
    """
    order = list(np.argsort(-scores, kind="stable"))
    area = np.clip(boxes[:, 2] - boxes[:, 0], 0, None) * np.clip(boxes[:, 3] - boxes[:, 1], 0, None)
    keep: list[int] = []
    for i in order:
        ok = True
        for j in keep:
            w = min(boxes[i, 2], boxes[j, 2]) - max(boxes[i, 0], boxes[j, 0])
            h = min(boxes[i, 3], boxes[j, 3]) - max(boxes[i, 1], boxes[j, 1])
            inter = max(w, 0.0) * max(h, 0.0)
            union = area[i] + area[j] - inter
            if union > 0 and inter / union > iou:
                ok = False
                break
        if ok:
            keep.append(int(i))
    return keep


class OwlSamDetector:
    """OWLv2 boxes for every prompt of ``detect.foundation.prompts``, SAM's mask in each box."""

    def __init__(self, cfg: DetectConfig):
        from transformers import Owlv2ForObjectDetection, Owlv2Processor, SamModel, SamProcessor

        f = self.f = cfg.foundation
        self.device = torch_device(cfg.device, "detect.device")
        det_dir = model_dir(f.detector, cfg.allow_download, "detect.foundation.detector")
        seg_dir = model_dir(f.segmenter, cfg.allow_download, "detect.foundation.segmenter")
        self.det = Owlv2ForObjectDetection.from_pretrained(det_dir, local_files_only=True).eval().to(self.device)
        self.det_proc = Owlv2Processor.from_pretrained(det_dir, local_files_only=True)
        self.seg = SamModel.from_pretrained(seg_dir, local_files_only=True).eval().to(self.device)
        self.seg_proc = SamProcessor.from_pretrained(seg_dir, local_files_only=True)
        self.queries = [(label, p) for label, prompts in f.prompts.items() for p in prompts]
        self.sources = {"detector": str(det_dir), "segmenter": str(seg_dir)}

    @torch.inference_mode()
    def __call__(self, rgb: np.ndarray) -> list[Detection]:
        """Detections of one uint8 [H, W, 3] image."""
        H, W = rgb.shape[:2]
        f = self.f
        texts = [p for _, p in self.queries]
        inp = self.det_proc(text=[texts], images=[rgb], return_tensors="pt", padding="max_length", truncation=True)
        out = self.det(**{k: v.to(self.device) for k, v in inp.items()})
        S = max(H, W)  # OWLv2 pads the image to a square at the bottom and right
        r = self.det_proc.post_process_grounded_object_detection(
            out, threshold=f.box_threshold, target_sizes=torch.tensor([[S, S]]))[0]
        boxes = r["boxes"].float().cpu().numpy().reshape(-1, 4)
        scores = r["scores"].float().cpu().numpy().reshape(-1)
        if not (np.isfinite(boxes).all() and np.isfinite(scores).all()):
            raise NonFiniteError("detect: OWLv2 gave non-finite boxes or scores")
        labels = [self.queries[int(q)][0] for q in r["labels"].cpu().numpy().reshape(-1)]
        boxes = np.clip(boxes, 0, [W, H, W, H])
        keep: list[int] = []
        for lab in sorted(set(labels)):
            idx = np.array([i for i, x in enumerate(labels) if x == lab])
            keep += [int(idx[k]) for k in box_nms(boxes[idx], scores[idx], f.nms_iou)]
        keep = sorted(keep, key=lambda i: -scores[i])[:f.max_per_frame]
        keep = [i for i in keep if boxes[i, 2] - boxes[i, 0] >= 1 and boxes[i, 3] - boxes[i, 1] >= 1]
        if not keep:
            return []
        sin = self.seg_proc(images=[rgb], input_boxes=[boxes[keep].tolist()], return_tensors="pt")
        emb = self.seg.get_image_embeddings(sin["pixel_values"].to(self.device))
        so = self.seg(image_embeddings=emb, input_boxes=sin["input_boxes"].to(self.device), multimask_output=False)
        masks = self.seg_proc.image_processor.post_process_masks(
            so.pred_masks.cpu(), sin["original_sizes"], sin["reshaped_input_sizes"])[0][:, 0].numpy()
        dets = []
        yy, xx = np.mgrid[0:H, 0:W]
        for m, i in zip(masks, keep):
            x0, y0, x1, y1 = boxes[i]
            m = m & (xx >= np.floor(x0)) & (xx < np.ceil(x1)) & (yy >= np.floor(y0)) & (yy < np.ceil(y1))
            if m.sum() >= (f.min_area_px if labels[i] != "handle" else max(1, f.min_area_px // 3)):
                dets.append(Detection(m, labels[i], float(scores[i])))
        return dets


class DepthAnythingPriors:
    """Depth Anything (any ``transformers`` depth-estimation model): relative or metric depth,
    and the normals of that depth."""

    def __init__(self, cfg: PriorsConfig):
        from transformers import AutoImageProcessor, AutoModelForDepthEstimation

        self.cfg = cfg
        self.device = torch_device(cfg.device, "priors.device")
        d = model_dir(cfg.depth_model, cfg.allow_download, "priors.depth_model")
        self.model = AutoModelForDepthEstimation.from_pretrained(d, local_files_only=True).eval().to(self.device)
        self.proc = AutoImageProcessor.from_pretrained(d, local_files_only=True)
        self.metric = getattr(self.model.config, "depth_estimation_type", "relative") == "metric"
        self.sources = {"depth": str(d)}

    @torch.inference_mode()
    def __call__(self, rgb: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray | None]:
        """(float32 [H, W] depth, float16 [H, W, 3] normals or None) of one uint8 image."""
        H, W = rgb.shape[:2]
        ws = self.cfg.working_size
        inp = self.proc(images=[rgb], return_tensors="pt", size={"height": ws, "width": ws})
        pred = self.model(pixel_values=inp["pixel_values"].to(self.device)).predicted_depth.float().cpu()
        up = F.interpolate(pred.reshape(1, 1, *pred.shape[-2:]), size=(H, W), mode="bicubic", align_corners=False)[0, 0]
        if not torch.isfinite(up).all():
            raise NonFiniteError("priors: the depth model gave non-finite values")
        if self.metric:
            depth = up.clamp_min(1e-3).numpy()
        else:  # affine-invariant inverse depth -> a positive depth (see PriorsConfig)
            d = up.clamp_min(0)
            p99 = float(torch.quantile(d.reshape(-1)[:: max(1, d.numel() // 200_000)], 0.99))
            depth = (1.0 / (d / max(p99, 1e-12) + self.cfg.inverse_shift)).numpy()
        depth = depth.astype(np.float32)
        normal = normals_from_depth(depth, intr).astype(np.float16) if self.cfg.normals else None
        return depth, normal
