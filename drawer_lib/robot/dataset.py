"""The demonstrations as a LeRobot dataset (codebase version v3.0, what ``lerobot`` >= 0.4
loads with ``LeRobotDataset(repo_id, root=...)`` without conversion), written with pyarrow.

Why our own writer: ``lerobot`` >= 0.5 needs Python 3.12 and 0.4.x pins a torch other than
this project's, so the package cannot be installed beside it; the format is files, and this
module writes exactly them (the tests read them back with Hugging Face ``datasets`` and pandas,
the calls lerobot's loader makes).

Layout under ``root``:

* ``data/chunk-000/file-000.parquet``: every frame, episodes back to back (one row group
  each); a column per feature: vectors as ``fixed_size_list<float>[N]``, shape-[1] features
  as scalars, images as ``struct<bytes: binary, path: string>`` holding a PNG;
* ``meta/info.json``: version, fps, counts, path templates, ``features`` (dtype, shape, names);
* ``meta/episodes/chunk-000/file-000.parquet``: per episode its index, tasks, length, file and
  row range (``dataset_from_index`` inclusive, ``dataset_to_index`` exclusive);
* ``meta/tasks.parquet``: the task strings (pandas index ``task``) and their ``task_index``;
* ``meta/stats.json``: per feature min, max, mean, std, count and the quantiles q01, q10, q50,
  q90, q99 (images per channel, shape [3, 1, 1], scaled to [0, 1]).
"""

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from PIL import Image

from drawer_lib.errors import InputError

CODEBASE_VERSION = "v3.0"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
DEFAULT_FEATURES = ("timestamp", "frame_index", "episode_index", "index", "task_index")


@dataclass
class Episode:
    """One episode: its task (a sentence) and its frames, ``frames[name]`` [T, ...] per feature
    (float vectors [T, N], scalars [T], images [T, H, W, 3] uint8)."""

    task: str
    frames: dict[str, np.ndarray]

    @property
    def length(self) -> int:
        return len(next(iter(self.frames.values())))


def _png(img: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img, np.uint8)).save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def _stats(x: np.ndarray, image: bool) -> dict:
    """min / max / mean / std / count and quantiles over axis 0 (per channel for images)."""
    if image:
        v = x.reshape(-1, x.shape[-1]).astype(np.float64) / 255.0  # [T*H*W, 3]
        shape = (3, 1, 1)
    else:
        v = x.reshape(len(x), -1).astype(np.float64)
        shape = (v.shape[1],)
    out = {"min": v.min(0), "max": v.max(0), "mean": v.mean(0), "std": v.std(0)}
    out |= {f"q{round(q * 100):02d}": np.quantile(v, q, axis=0) for q in QUANTILES}
    out = {k: np.asarray(a, np.float64).reshape(shape).tolist() for k, a in out.items()}
    out["count"] = [len(x)]
    return out


def write_lerobot(root: Path, episodes: list[Episode], features: dict[str, dict], fps: int,
                  robot_type: str | None = None) -> dict:
    """Write ``episodes`` as a LeRobot v3.0 dataset into ``root`` (created; must not exist or be
    empty). ``features``: name -> {"dtype", "shape", "names"} for the recorded features (the
    default ones are added). Returns info.json's dict."""
    root = Path(root)
    if root.exists() and any(root.iterdir()):
        raise InputError(f"{root}: not empty; a dataset is written into a fresh folder")
    if not episodes:
        raise InputError("write_lerobot: no episodes")
    for name, f in features.items():
        if "/" in name or name in DEFAULT_FEATURES:
            raise InputError(f"write_lerobot: feature name {name!r} is reserved or contains '/'")
        for ep in episodes:
            if name not in ep.frames:
                raise InputError(f"write_lerobot: episode {ep.task!r} lacks feature {name!r}")
            if tuple(ep.frames[name].shape[1:]) != tuple(f["shape"]) and not (
                    tuple(f["shape"]) == (1,) and ep.frames[name].ndim == 1):
                raise InputError(f"write_lerobot: feature {name!r} has shape {ep.frames[name].shape[1:]}, "
                                 f"info says {f['shape']}")
    tasks = list(dict.fromkeys(ep.task for ep in episodes))
    feats = dict(features)
    feats |= {"timestamp": {"dtype": "float32", "shape": [1], "names": None}}
    feats |= {k: {"dtype": "int64", "shape": [1], "names": None} for k in DEFAULT_FEATURES[1:]}

    def arrow_type(f):
        base = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_(),
                "string": pa.string()}
        if f["dtype"] == "image":
            return pa.struct([("bytes", pa.binary()), ("path", pa.string())])
        t = base[f["dtype"]]
        return t if list(f["shape"]) == [1] else pa.list_(t, int(np.prod(f["shape"])))

    schema = pa.schema([(k, arrow_type(f)) for k, f in feats.items()])
    data_file = root / DATA_PATH.format(chunk_index=0, file_index=0)
    data_file.parent.mkdir(parents=True, exist_ok=True)
    ep_rows, index = [], 0
    all_cols: dict[str, list[np.ndarray]] = {k: [] for k in feats}
    with pq.ParquetWriter(data_file, schema, compression="snappy") as w:
        for e, ep in enumerate(episodes):
            T = ep.length
            cols = {}
            for k, f in features.items():
                a = ep.frames[k]
                if f["dtype"] == "image":
                    cols[k] = pa.array([{"bytes": _png(im), "path": f"frame-{i:06d}.png"} for i, im in enumerate(a)],
                                       type=schema.field(k).type)
                elif list(f["shape"]) == [1]:
                    cols[k] = pa.array(np.asarray(a).reshape(T).astype(f["dtype"]), type=schema.field(k).type)
                else:
                    flat = pa.array(np.asarray(a, f["dtype"]).reshape(-1))
                    cols[k] = pa.FixedSizeListArray.from_arrays(flat, int(np.prod(f["shape"])))
                all_cols[k].append(np.asarray(a))
            defaults = {"timestamp": np.arange(T, dtype=np.float32) / fps, "frame_index": np.arange(T),
                        "episode_index": np.full(T, e), "index": np.arange(index, index + T),
                        "task_index": np.full(T, tasks.index(ep.task))}
            for k, v in defaults.items():
                cols[k] = pa.array(v.astype(feats[k]["dtype"]))
                all_cols[k].append(v)
            w.write_table(pa.table([cols[k] for k in feats], schema=schema))
            ep_rows.append({"episode_index": e, "tasks": [ep.task], "length": T, "data/chunk_index": 0,
                            "data/file_index": 0, "dataset_from_index": index, "dataset_to_index": index + T,
                            "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
            index += T
    ep_file = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    ep_file.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(ep_rows), ep_file)
    pandas_meta = {"index_columns": ["task"], "column_indexes": [
        {"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
         "metadata": {"encoding": "UTF-8"}}], "columns": [
        {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
         "metadata": None},
        {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__}, "pandas_version": "2.2.3"}
    tt = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())})
    pq.write_table(tt.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()}), root / "meta" / "tasks.parquet")
    stats = {k: _stats(np.concatenate(v), feats[k]["dtype"] == "image") for k, v in all_cols.items()
             if feats[k]["dtype"] != "string"}
    (root / "meta" / "stats.json").write_text(json.dumps(stats, indent=1))
    info = {"codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": len(episodes),
            "total_frames": index, "total_tasks": len(tasks), "chunks_size": 1000, "data_files_size_in_mb": 100,
            "video_files_size_in_mb": 200, "fps": int(fps), "splits": {"train": f"0:{len(episodes)}"},
            "data_path": DATA_PATH, "video_path": None, "features": feats}
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=2))
    return info
