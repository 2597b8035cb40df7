"""Find, verify and load pretrained network weights by name.

Every weight file the package knows has an entry in :data:`REGISTRY`: its file name, the URL it can be
downloaded from (if any) and the hash it must have. :func:`resolve_weights` looks for a network's file in
this order and returns the first one found:

1. an explicit ``path`` argument (any file name; it must match one of the network's known files),
2. the file named by the network's environment variable (``PLATESYNTH_FID_WEIGHTS`` for the FID InceptionV3),
3. a known file name inside ``$PLATESYNTH_WEIGHTS_DIR``,
4. a known file name inside the torch hub cache, ``torch.hub.get_dir()/checkpoints``
   (``$TORCH_HOME/hub/checkpoints``, by default ``~/.cache/torch/hub/checkpoints``),
5. a download into that cache, unless ``PLATESYNTH_OFFLINE=1`` or ``download=False``.

If none applies, :class:`~platesynth.errors.WeightsNotFoundError` is raised with a one-line message that lists
every option. Local files are hash-checked as well as downloads: a corrupt or different file is an error that
names the file, never a silently wrong metric.

Two hash conventions are used:

* ``sha256``: a prefix (torch hub convention, the 8 hex digits in the file name) or the full sha256 of the
  file's bytes, used for files published upstream (torchvision, pytorch-fid);
* ``content_sha256``: the sha256 of the file's *tensors* whose keys start with ``features.``: for each key in
  sorted order, the key's UTF-8 bytes then the tensor's raw bytes. It is used for the reduced backbone files
  (``*_features-*.pth``) that hold only the convolutional part of a torchvision network; see the weights README
  of the developers' shared folder.

Public API: :data:`REGISTRY`, :class:`WeightsFile`, :class:`NetworkWeights`, :func:`resolve_weights`,
:func:`load_weights`, :func:`file_sha256`, :func:`content_sha256`; the constants :data:`WEIGHTS_DIR_ENV`,
:data:`FID_WEIGHTS_ENV`, :data:`OFFLINE_ENV`.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import torch

from platesynth.errors import ParameterError, WeightsNotFoundError
from platesynth.limits import RefusedFileError, load_torch_file

WEIGHTS_DIR_ENV = "PLATESYNTH_WEIGHTS_DIR"
FID_WEIGHTS_ENV = "PLATESYNTH_FID_WEIGHTS"
OFFLINE_ENV = "PLATESYNTH_OFFLINE"


@dataclass(frozen=True)
class WeightsFile:
    """One known weight file.

    Attributes
    ----------
    file_name : str
        Name looked for in the weights directory and the torch hub cache, and given to a download.
    url : str or None
        Where to download it; None for files that are not published on their own.
    sha256 : str
        Prefix or full sha256 of the file's bytes ("" if the file is checked by content instead).
    content_sha256 : str
        sha256 of the ``features.*`` tensors (see the module docstring; "" if the file is checked by bytes).
    """

    file_name: str
    url: str | None
    sha256: str = ""
    content_sha256: str = ""


@dataclass(frozen=True)
class NetworkWeights:
    """The weight files that can serve one network, in order of preference.

    Attributes
    ----------
    name : str
        Registry key, e.g. ``"alexnet"``.
    description : str
        Human-readable name used in error messages.
    files : tuple of WeightsFile
        Accepted files; the first ones found locally win, only those with a URL are downloaded.
    file_env : str or None
        Environment variable that may point directly at the file.
    """

    name: str
    description: str
    files: tuple[WeightsFile, ...]
    file_env: str | None = None


_ALEXNET_FEATURES_SHA256 = "44534cd66e37ce9a6258bb5e845ef8cd47c33aa68024441c7e616d63c0c1c41a"
_SQUEEZENET_FEATURES_SHA256 = "9a3cd24c3da63ec76ec50dabac44e862029b5c84992e5ddd582be22d0f9ef388"

REGISTRY: dict[str, NetworkWeights] = {
    "alexnet": NetworkWeights(
        name="alexnet",
        description="AlexNet (ImageNet, torchvision) weights",
        files=(
            WeightsFile("alexnet_features-7be5be79.pth", None, content_sha256=_ALEXNET_FEATURES_SHA256),
            WeightsFile(
                "alexnet-owt-7be5be79.pth",
                "https://download.pytorch.org/models/alexnet-owt-7be5be79.pth",
                sha256="7be5be79",
            ),
        ),
    ),
    "squeezenet1_1": NetworkWeights(
        name="squeezenet1_1",
        description="SqueezeNet 1.1 (ImageNet, torchvision) weights",
        files=(
            WeightsFile("squeezenet1_1_features-b8a52dc0.pth", None, content_sha256=_SQUEEZENET_FEATURES_SHA256),
            WeightsFile(
                "squeezenet1_1-b8a52dc0.pth",
                "https://download.pytorch.org/models/squeezenet1_1-b8a52dc0.pth",
                sha256="b8a52dc0",
            ),
        ),
    ),
    "inception_fid": NetworkWeights(
        name="inception_fid",
        description="FID InceptionV3 weights (pytorch-fid)",
        files=(
            WeightsFile(
                "pt_inception-2015-12-05-6726825d.pth",
                "https://github.com/mseitzer/pytorch-fid/releases/download/fid_weights/"
                "pt_inception-2015-12-05-6726825d.pth",
                sha256="6726825d",
            ),
        ),
        file_env=FID_WEIGHTS_ENV,
    ),
}

# Files already verified in this process, keyed by (resolved path, size, mtime) so that a changed file is re-checked.
_verified: set[tuple[str, int, int]] = set()


def file_sha256(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes, read in 1 MiB chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def content_sha256(state_dict: Mapping[str, torch.Tensor], prefix: str = "features.") -> str:
    """Hex sha256 of the tensors whose key starts with ``prefix``: sorted keys, each key's bytes then its raw data."""
    digest = hashlib.sha256()
    for key in sorted(k for k in state_dict if k.startswith(prefix)):
        digest.update(key.encode("utf-8"))
        digest.update(state_dict[key].detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def _read_state_dict(path: Path) -> dict[str, torch.Tensor]:
    try:
        state_dict = load_torch_file(path)  # tensors and plain data only
    except RefusedFileError as exc:
        raise WeightsNotFoundError(f"{path}: cannot read weights ({str(exc).removeprefix(f'{path}: ')})") from None
    except Exception as exc:  # torch raises many types (zip, runtime, EOF) for a broken file
        first = (str(exc).strip().splitlines() or [""])[0]
        raise WeightsNotFoundError(f"{path}: cannot read weights ({exc.__class__.__name__}: {first})") from None
    if not isinstance(state_dict, Mapping):
        raise WeightsNotFoundError(f"{path}: not a state dict (found {type(state_dict).__name__})")
    return dict(state_dict)


def _matches(path: Path, network: NetworkWeights, file_digest: str) -> bool:
    if any(f.sha256 and file_digest.startswith(f.sha256) for f in network.files):
        return True
    content_hashes = {f.content_sha256 for f in network.files if f.content_sha256}
    return bool(content_hashes) and content_sha256(_read_state_dict(path)) in content_hashes


def _verify(path: Path, network: NetworkWeights) -> Path:
    """Return ``path`` if it is one of ``network``'s known files, else raise naming the file and what was expected."""
    if not path.is_file():
        raise WeightsNotFoundError(f"{path}: no such weights file")
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if key in _verified:
        return path
    file_digest = file_sha256(path)
    if not _matches(path, network, file_digest):
        expected = ", ".join(
            f"{f.file_name} (sha256 {f.sha256}...)" if f.sha256 else f"{f.file_name} (features content sha256 "
            f"{f.content_sha256[:16]}...)"
            for f in network.files
        )
        raise WeightsNotFoundError(
            f"{path}: sha256 {file_digest[:16]}... is not one of the known {network.description}: expected {expected}; "
            "the file is corrupt or different, delete or replace it"
        )
    _verified.add(key)
    return path


def _cache_dir() -> Path:
    return Path(torch.hub.get_dir()) / "checkpoints"


def _offline() -> bool:
    return os.environ.get(OFFLINE_ENV, "").strip().lower() in ("1", "true", "yes", "on")


def _download(url: str, destination: Path) -> None:
    """Download ``url`` to ``destination`` (a temporary name; the caller verifies and renames it)."""
    torch.hub.download_url_to_file(url, str(destination), progress=True)


def _download_into_cache(weights_file: WeightsFile, network: NetworkWeights) -> Path:
    target = _cache_dir() / weights_file.file_name
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{weights_file.file_name}.", suffix=".partial", dir=target.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        _download(weights_file.url, tmp)
        try:
            _verify(tmp, network)
        except WeightsNotFoundError:
            raise WeightsNotFoundError(
                f"download of {weights_file.url} has sha256 {file_sha256(tmp)[:16]}..., expected "
                f"{weights_file.sha256 or weights_file.content_sha256[:16]}...: discarded"
            ) from None
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
    return target


def _get_network(network: str | NetworkWeights) -> NetworkWeights:
    if isinstance(network, NetworkWeights):
        return network
    try:
        return REGISTRY[network]
    except KeyError:
        raise ParameterError(f"unknown network {network!r}; known: {', '.join(REGISTRY)}") from None


def resolve_weights(
    network: str | NetworkWeights, path: str | os.PathLike | None = None, *, download: bool = True
) -> Path:
    """Find and verify the weight file of a network.

    Parameters
    ----------
    network : str or NetworkWeights
        A key of :data:`REGISTRY` (``"alexnet"``, ``"squeezenet1_1"``, ``"inception_fid"``) or an entry.
    path : str or path-like, optional
        Explicit file; when given it is the only candidate.
    download : bool
        Allow a download into the torch hub cache as the last resort (also disabled by ``PLATESYNTH_OFFLINE=1``).

    Returns
    -------
    pathlib.Path
        A verified weight file.

    Raises
    ------
    WeightsNotFoundError
        If no file is found (the message lists every option), or a file found is corrupt or not a known one.
    """
    entry = _get_network(network)
    if path is not None:
        return _verify(Path(path).expanduser(), entry)
    if entry.file_env and os.environ.get(entry.file_env):
        return _verify(Path(os.environ[entry.file_env]).expanduser(), entry)
    directories = [Path(os.environ[WEIGHTS_DIR_ENV]).expanduser()] if os.environ.get(WEIGHTS_DIR_ENV) else []
    directories.append(_cache_dir())
    for directory in directories:
        for weights_file in entry.files:
            candidate = directory / weights_file.file_name
            if candidate.is_file():
                return _verify(candidate, entry)

    downloadable = [f for f in entry.files if f.url]
    if not download:
        download_state = "downloads disabled by the caller"
    elif _offline():
        download_state = f"downloads disabled by {OFFLINE_ENV}=1"
    elif not downloadable:
        download_state = "no download URL known"
    else:
        failures = []
        for weights_file in downloadable:
            try:
                return _download_into_cache(weights_file, entry)
            except WeightsNotFoundError as exc:
                failures.append(str(exc))
            except OSError as exc:  # urllib's URLError and HTTPError are OSErrors
                failures.append(f"download of {weights_file.url} failed ({exc.__class__.__name__}: {exc})")
        download_state = "; ".join(failures)
    names = " or ".join(f.file_name for f in entry.files)
    urls = ", ".join(f.url for f in downloadable) or "none"
    env_file = f"set {entry.file_env} to the file, " if entry.file_env else ""
    weights_dir = os.environ.get(WEIGHTS_DIR_ENV) or "unset"
    raise WeightsNotFoundError(
        f"{entry.description} not found ({names}). Options: pass the file's path, {env_file}"
        f"set {WEIGHTS_DIR_ENV} to a folder holding it (now {weights_dir}), put it in the torch hub cache "
        f"{_cache_dir()}, or download it from {urls} ({download_state})"
    )


def load_weights(
    network: str | NetworkWeights, path: str | os.PathLike | None = None, *, download: bool = True
) -> dict[str, torch.Tensor]:
    """Resolve (see :func:`resolve_weights`) and load a network's state dict on the CPU.

    Returns
    -------
    dict of str to torch.Tensor
        The file's tensors with their original (torchvision / pytorch-fid) key names.
    """
    return _read_state_dict(resolve_weights(network, path, download=download))
