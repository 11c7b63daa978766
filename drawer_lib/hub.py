"""Foundation models' weights (the detect and priors stages' models, articulate's vision-language
model): a local folder, or the Hugging Face cache; fetched only when the user allows it. A
missing model is one line that says how to get it."""

from dataclasses import dataclass
from pathlib import Path

from drawer_lib.errors import InputError


@dataclass(frozen=True)
class HubModel:
    """A foundation model's weights: ``path``, a local folder as ``save_pretrained`` writes it,
    or else ``repo`` (at ``revision``) from the Hugging Face cache (``HF_HOME``)."""

    repo: str
    path: str | None = None
    revision: str | None = None


def model_dir(m: HubModel, allow_download: bool, key: str) -> Path:
    """The folder holding ``m``'s ``config.json`` and weights. ``key``: the config key that
    names it (for the error). Raises :class:`InputError` when it is not on this machine and
    ``allow_download`` is false."""
    if m.path:
        p = Path(m.path).expanduser()
        if not (p / "config.json").is_file():
            raise InputError(f"{key}.path = {p}: no config.json there (a folder written by save_pretrained, or "
                             f"`hf download {m.repo} --local-dir {p}`)")
        return p
    from huggingface_hub import snapshot_download
    from huggingface_hub.errors import LocalEntryNotFoundError

    try:
        return Path(snapshot_download(m.repo, revision=m.revision, local_files_only=not allow_download))
    except LocalEntryNotFoundError:
        raise InputError(f"{key}.repo = {m.repo}: not in the Hugging Face cache; fetch it with `hf download "
                         f"{m.repo}` (or set {key.split('.', 1)[0]}.allow_download=true, or {key}.path to a "
                         "local copy)") from None
