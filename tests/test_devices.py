"""Device names checked before any work (drawer_lib/devices.py): a name torch does not know, a
device type the project does not run on, CUDA where torch sees none, a CUDA index past the
machine's cards: a ConfigError naming the setting. The detect and detector settings use it."""

import pytest
import torch

from drawer_lib.detect.builtin import BuiltinDetector, TinyUNet, save_detector
from drawer_lib.detect.config import BuiltinDetectConfig, DetectorTrainConfig
from drawer_lib.detect.train import Sample, fit_detector, fit_fingerprint
from drawer_lib.devices import cuda_numerics, device_name, torch_device
from drawer_lib.errors import ConfigError

no_cuda = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA present: the gpu tests cover it")


def test_cpu_is_the_cpu():
    assert torch_device("cpu", "k") == torch.device("cpu")
    assert device_name("cpu") == "cpu" and device_name(torch.device("cpu")) == "cpu"


@pytest.mark.parametrize("name, match", [("gpu0", "not a torch device"), ("", "not a torch device"),
                                         ("meta", "only cpu and cuda"), ("cuda:-1", "")])
def test_names_torch_or_the_project_cannot_use_are_config_errors(name, match):
    with pytest.raises(ConfigError, match=rf"detect\.device = {name!r}.*{match}"):
        torch_device(name, "detect.device")


@no_cuda
def test_cuda_without_cuda_says_so_and_what_to_do():
    with pytest.raises(ConfigError, match=r"detector\.device = 'cuda': this torch .* sees no CUDA device; use cpu"):
        torch_device("cuda", "detector.device")


@pytest.mark.gpu
def test_a_cuda_index_past_the_cards_is_a_config_error():
    n = torch.cuda.device_count()
    assert torch_device("cuda:0", "k").index == 0 and device_name("cuda").startswith("cuda:0 ")
    with pytest.raises(ConfigError, match=f"has {n} CUDA device"):
        torch_device(f"cuda:{n}", "k")


@no_cuda
def test_a_detector_fit_or_the_detect_stage_on_absent_cuda_stops_before_any_work(tmp_path):
    samples = [Sample(torch.zeros(3, 8, 8), torch.zeros(8, 8, dtype=torch.long))]
    with pytest.raises(ConfigError, match=r"detector\.device = 'cuda'.*use detector\.device: cpu"):
        fit_detector(samples, DetectorTrainConfig(width=4, steps=2, batch=1, crop=8, device="cuda"), seed=0)
    save_detector(tmp_path / "w.pt", TinyUNet(4), {})
    with pytest.raises(ConfigError, match=r"detect\.device = 'cuda'"):
        BuiltinDetector(tmp_path / "w.pt", BuiltinDetectConfig(), "cuda")


def test_cuda_numerics_turn_tf32_and_autotuning_off_and_leave_the_cpu_alone():
    """cuDNN's own default is TF32 on; inside the context it is off (the flags are set on a
    CPU build too), and they are back after it."""
    before = (torch.backends.cudnn.allow_tf32, torch.backends.cudnn.benchmark, torch.backends.cudnn.deterministic)
    with cuda_numerics(torch.device("cuda")):
        assert not torch.backends.cudnn.allow_tf32 and not torch.backends.cudnn.benchmark
        assert torch.backends.cudnn.deterministic
    assert (torch.backends.cudnn.allow_tf32, torch.backends.cudnn.benchmark, torch.backends.cudnn.deterministic) == before
    with cuda_numerics(torch.device("cpu")):
        assert torch.backends.cudnn.allow_tf32 == before[0]


def test_the_detector_is_applied_under_the_numerics_of_its_device(monkeypatch):
    """``class_probs`` enters :func:`cuda_numerics` with the network's device (on a card: no
    TF32, as in its fit)."""
    import numpy as np

    import drawer_lib.detect.builtin as builtin

    seen = []

    def spy(dev):
        seen.append(dev)
        return cuda_numerics(dev)

    monkeypatch.setattr(builtin, "cuda_numerics", spy)
    builtin.class_probs(TinyUNet(4).eval(), np.zeros((8, 8, 3), np.uint8), 8)
    assert seen == [torch.device("cpu")]


def test_a_fit_state_saved_on_one_device_is_not_gone_on_from_on_another():
    """The device is a fit setting: its last bits differ, so its saved state must not mix."""
    samples = [Sample(torch.zeros(3, 8, 8), torch.zeros(8, 8, dtype=torch.long))]
    a = fit_fingerprint(samples, DetectorTrainConfig(device="cpu"), 0)
    assert a != fit_fingerprint(samples, DetectorTrainConfig(device="cuda"), 0)
    assert a == fit_fingerprint(samples, DetectorTrainConfig(device="cpu", checkpoint_every=7), 0)


def test_the_device_benchmark_renders_saves_and_times_a_fit(tmp_path, root):
    """scripts/bench_detector_device.py: views rendered and saved, read back without the
    renderer, a few steps timed per device; a device this machine lacks is one error line."""
    import json
    import subprocess
    import sys

    script = [sys.executable, str(root / "scripts" / "bench_detector_device.py")]
    small = ["--set", "batch=2", "crop=64", "width=8", "frame_every=12"]
    r = subprocess.run(script + ["--kitchens", "0", "--save-views", str(tmp_path / "v.npz"), *small],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    r = subprocess.run(script + ["--views", str(tmp_path / "v.npz"), "--device", "cpu", "--steps", "4", "--warmup", "1",
                                 "--out", str(tmp_path / "o.json"), *small], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    (row,) = json.loads((tmp_path / "o.json").read_text())["rows"]
    assert row["device"] == "cpu" and row["steps"] == 4 and row["views"] >= 2 and row["s_per_step_median"] > 0
    assert abs(row["whole_fit_train_min"] - 6000 * row["s_per_step_median"] / 60) <= 0.011  # 5000 + 1000 averaging
    if not torch.cuda.is_available():
        r = subprocess.run(script + ["--views", str(tmp_path / "v.npz"), "--device", "cuda", "--steps", "2", *small],
                           capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode != 0 and r.stderr.strip().splitlines()[-1].startswith("error: detector.device = 'cuda'")
