"""What makes the render command fast without changing its files: the PNG encoder, the mask reader, the workers'
share of the CPUs and quick exit, and workers that do not run the console script again."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import types

import numpy as np
import pytest
import tifffile
from PIL import Image

from platesynth.data.executor import ProcessExecutor, limit_threads
from platesynth.errors import ImageReadError
from platesynth.io import encode_png, image_size, read_image, read_mask, write_png


@pytest.mark.parametrize("shape", [(5, 7), (5, 7, 1), (5, 7, 3), (6, 4, 4), (1, 1, 3), (97, 131, 3)])
@pytest.mark.parametrize("level", [0, 1, 6, 9])
def test_encode_png_is_lossless(shape, level):
    image = np.random.default_rng(sum(shape) + level).integers(0, 256, shape, dtype=np.uint8)
    decoded = np.asarray(Image.open(io.BytesIO(encode_png(image, level))))
    np.testing.assert_array_equal(decoded.reshape(shape), image)


def test_encode_png_takes_views_and_refuses_other_types():
    image = np.random.default_rng(1).integers(0, 256, (20, 30, 3), dtype=np.uint8)[::-1, ::2]
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(encode_png(image)))), image)
    with pytest.raises(ValueError, match="8-bit"):
        encode_png(np.zeros((4, 4), np.uint16))
    with pytest.raises(ValueError, match="8-bit"):
        encode_png(np.zeros((4, 4, 2), np.uint8))


def test_write_png_every_kind_and_level_reads_back(tmp_path):
    rng = np.random.default_rng(2)
    for name, image in {
        "rgb": rng.integers(0, 256, (30, 40, 3), dtype=np.uint8),
        "gray": rng.integers(0, 256, (30, 40), dtype=np.uint8),
        "gray16": rng.integers(0, 65536, (30, 40), dtype=np.uint16),  # through Pillow
    }.items():
        for level in (1, 6):
            path = tmp_path / f"{name}{level}.png"
            write_png(path, image, compress_level=level)
            np.testing.assert_array_equal(read_image(path), image)
            assert image_size(path) == (40, 30)


def test_read_mask_one_reader_for_every_mask(tmp_path):
    mask = np.arange(12, dtype=np.uint16).reshape(3, 4)
    tifffile.imwrite(tmp_path / "m.tif", mask)
    np.testing.assert_array_equal(read_mask(tmp_path / "m.tif"), mask)
    tifffile.imwrite(tmp_path / "rgb.tif", np.stack([mask] * 3, axis=-1), photometric="rgb")
    np.testing.assert_array_equal(read_mask(tmp_path / "rgb.tif", first_channel=True), mask)
    with pytest.raises(ImageReadError, match="2-D integer"):
        read_mask(tmp_path / "rgb.tif")
    tifffile.imwrite(tmp_path / "float.tif", mask.astype(np.float32))
    with pytest.raises(ImageReadError, match="2-D integer"):
        read_mask(tmp_path / "float.tif")
    with pytest.raises(ImageReadError, match="no such mask"):
        read_mask(tmp_path / "missing.tif")
    (tmp_path / "bad.tif").write_bytes(b"not a tiff")
    with pytest.raises(ImageReadError, match="cannot read mask"):
        read_mask(tmp_path / "bad.tif")
    with pytest.raises(ImageReadError, match="cannot read image"):
        image_size(tmp_path / "bad.tif")


def numba_threads() -> tuple[int, str | None]:
    """Worker task of the tests: numba's thread count and the environment's OMP_NUM_THREADS in this process."""
    import numba

    return numba.get_num_threads(), os.environ.get("OMP_NUM_THREADS")


def test_process_workers_share_the_cpus(monkeypatch):
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert ProcessExecutor(workers=1).threads_per_worker == len(os.sched_getaffinity(0))
    assert ProcessExecutor(workers=10_000).threads_per_worker == 1
    with ProcessExecutor(workers=2, threads_per_worker=1) as executor:
        assert set(executor.map_unordered(_call, [numba_threads] * 4)) == {(1, "1")}


def _call(function):
    return function()


def test_limit_threads_leaves_the_users_settings(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    limit_threads(1)
    assert os.environ["OMP_NUM_THREADS"] == "3" and os.environ["MKL_NUM_THREADS"] == "1"


def test_the_console_script_is_hidden_from_spawned_workers_while_a_command_runs(monkeypatch):
    from platesynth.cli import _workers_skip_the_script

    script = types.ModuleType("__main__")
    script.__file__ = "/somewhere/bin/platesynth"
    script.__spec__ = None
    monkeypatch.setitem(sys.modules, "__main__", script)
    with _workers_skip_the_script():
        assert not hasattr(script, "__file__")
    assert script.__file__ == "/somewhere/bin/platesynth"
    with pytest.raises(SystemExit), _workers_skip_the_script():
        raise SystemExit(0)
    assert script.__file__ == "/somewhere/bin/platesynth"


def test_workers_do_not_run_the_console_script(tmp_path):
    """A script like pip's ``platesynth`` console script: spawned workers do not run it again (it imported the whole
    command line in each of them), and the dataset is complete."""
    script = tmp_path / "platesynth_script.py"
    script.write_text(
        "import os\n"
        "import sys\n"
        "from platesynth.cli import main\n"
        "if __name__ != '__main__':\n"
        "    open(os.environ['SCRIPT_RUNS'], 'a').write(__name__ + '\\n')\n"
        "if __name__ == '__main__':\n"
        "    sys.exit(main())\n"
    )
    runs = tmp_path / "runs.txt"
    out = tmp_path / "out"
    command = [sys.executable, str(script), "render", "--out", str(out), "--count", "2", "--size", "64x48", "--workers", "2"]
    done = subprocess.run(command, capture_output=True, text=True, env={**os.environ, "SCRIPT_RUNS": str(runs)})
    assert done.returncode == 0, done.stderr
    assert len(list((out / "params").glob("*.json"))) == 2
    assert not runs.exists(), runs.read_text()
