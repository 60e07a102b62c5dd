"""Test helpers: procedural images and a tiny rendered data set in the CONTRACTS.md format.

No torch here (the no-torch tests use it too).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

TOOLS = Path(__file__).resolve().parents[1]
REPO = TOOLS.parent
CONFIGS = TOOLS / "configs"
FIXTURE_MODELS = Path(__file__).resolve().parent / "fixtures" / "models-smoke"
# Real images the project may read (never committed): the folder RAINDROP_SHARED_DATA names
# (ctest passes it, tests/CMakeLists.txt), else ../shared/data relative to the repo.
SHARED_DATA_ENV = "RAINDROP_SHARED_DATA"
DEFAULT_SHARED_DATA = REPO.parent / "shared" / "data"


def shared_data_dir() -> Path:
    """The real-image folder: $RAINDROP_SHARED_DATA when set and not empty, else
    ../shared/data beside the repository. Read on every call, so that it follows the
    environment (and monkeypatch)."""
    value = os.environ.get(SHARED_DATA_ENV, "").strip()
    return Path(value).expanduser() if value else DEFAULT_SHARED_DATA


def procedural_image(h: int, w: int, seed: int) -> np.ndarray:
    """A street-like HxWx3 uint8 RGB image: sky/ground gradient, blocks, a few discs, fine
    texture and noise. Deterministic for a seed."""
    rng = np.random.default_rng(seed)
    y = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None, None]
    x = np.linspace(0.0, 1.0, w, dtype=np.float32)[None, :, None]
    top, bottom = rng.uniform(0.3, 1.0, 3), rng.uniform(0.0, 0.6, 3)
    img = (1 - y) * top + y * bottom + 0.1 * np.sin(6.28 * (x * rng.uniform(1, 4) + y * rng.uniform(0, 2)))
    img = np.broadcast_to(img, (h, w, 3)).copy()
    for _ in range(int(rng.integers(3, 8))):
        y0, x0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        y1, x1 = min(h, y0 + int(rng.integers(2, max(3, h // 2)))), min(w, x0 + int(rng.integers(2, max(3, w // 2))))
        img[y0:y1, x0:x1] = rng.uniform(0, 1, 3)
    for _ in range(int(rng.integers(1, 4))):
        cy, cx, r = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(1, max(2, min(h, w) / 4))
        yy, xx = np.mgrid[0:h, 0:w]
        img[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = rng.uniform(0, 1, 3)
    img += rng.normal(0, 0.02, img.shape)
    return (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)


def add_drops(clean: np.ndarray, seed: int, count: int = 6) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """(rainy, mask 0/255, drops): discs whose inside shows a blurred, vertically flipped,
    brightened copy of the image, like a crude drop lens. rainy == clean outside the mask."""
    rng = np.random.default_rng(seed)
    h, w = clean.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    drops = []
    yy, xx = np.mgrid[0:h, 0:w]
    for _ in range(count):
        cy, cx = rng.uniform(0, h), rng.uniform(0, w)
        r = rng.uniform(2, max(3, min(h, w) / 6))
        mask[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = 255
        drops.append(
            {
                "center_cm": [float(cx), float(cy)],
                "footprint_radius_cm": float(r),
                "sphere_radius_cm": float(r) * 1.5,
                "contact_angle_deg": 40.0,
            }
        )
    lens = cv2.GaussianBlur(clean[::-1].copy(), (0, 0), 2.0)
    lens = np.clip(lens.astype(np.float32) * 1.1 + 8, 0, 255).astype(np.uint8)
    rainy = np.where(mask[:, :, None] > 0, lens, clean)
    return rainy, mask, drops


def _write_png(path: Path, img: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    assert cv2.imwrite(str(path), img), path


def manifest_record(
    sid: str, w: int, h: int, variant: int, seed: int, coverage: float, drops: list[dict], split: str
) -> dict:
    """A manifest line with every key CONTRACTS.md section 1 lists."""
    return {
        "id": sid,
        "rainy": f"rainy/{sid}.png",
        "clean": f"clean/{sid}.png",
        "mask": f"mask/{sid}.png",
        "width": w,
        "height": h,
        "source": f"procedural/{sid.rsplit('_v', 1)[0]}.png",
        "split": split,
        "variant": variant,
        "seed": seed,
        "camera": {"fx": 2262.52 * w / 2048, "fy": 2265.30 * h / 1024, "cx": w / 2, "cy": h / 2, "origin": "default"},
        "scene": {
            "glass_distance_cm": 30.0,
            "background_distance_cm": 1000.0,
            "tilt_deg": 40.0,
            "blur_diameter_px": 3.0,
        },
        "effects": ["refraction", "blur"],
        "drops": drops,
        "coverage": coverage,
        "renderer": "test-fixture 0",
        "an_unknown_key": {"readers": "must ignore it"},
    }


def write_dataset(
    root: Path, n: int = 6, h: int = 48, w: int = 64, seed: int = 0, splits: tuple[str, ...] = ("train",)
) -> Path:
    """A data set folder in the CONTRACTS.md section 1 format; returns ``root``."""
    root = Path(root)
    records = []
    for i in range(n):
        sid = f"src{i // 2:03d}_v{i % 2}"
        clean = procedural_image(h, w, seed * 1000 + i // 2)
        rainy, mask, drops = add_drops(clean, seed * 1000 + i)
        _write_png(root / "rainy" / f"{sid}.png", rainy)
        _write_png(root / "clean" / f"{sid}.png", clean)
        _write_png(root / "mask" / f"{sid}.png", mask)
        split = splits[i % len(splits)]
        records.append(manifest_record(sid, w, h, i % 2, seed + i, float((mask > 0).mean()), drops, split))
    records.sort(key=lambda r: r["id"])
    (root / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return root


def real_frames(max_count: int = 2) -> list[Path]:
    """A few real photographs from shared_data_dir() (empty when the folder is absent or
    has none): one each from cityscapes-mini/, real-raindrop/ and camvid/."""
    root = shared_data_dir()
    if not root.is_dir():
        return []
    found = sorted((root / "cityscapes-mini").rglob("*.png"))[:1]
    found += sorted((root / "real-raindrop").glob("*.png"))[:1]
    found += sorted((root / "camvid").rglob("*.png"))[:1]
    return found[:max_count] if max_count else found


def shared_data_missing() -> str:
    """The skip message of a test that found no real frames: which folder was looked at,
    why nothing was found, and how to name another one."""
    root = shared_data_dir()
    where = f"{SHARED_DATA_ENV}={root}" if os.environ.get(SHARED_DATA_ENV, "").strip() else f"{root} (default)"
    why = "has no PNG in cityscapes-mini/, real-raindrop/ or camvid/" if root.is_dir() else "not found"
    return (
        f"real-image folder {where} {why}: real-image checks skipped (procedural images still tested;"
        f" set {SHARED_DATA_ENV} to a folder of real photographs to run them)"
    )


def load_small_rgb(path: Path, max_side: int = 160) -> np.ndarray:
    """An RGB uint8 image resized so that its longer side is at most ``max_side`` (area)."""
    img = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    h, w = img.shape[:2]
    s = max_side / max(h, w)
    if s < 1:
        img = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    return img


def quiet_session(model_or_path):
    """An ONNX Runtime CPU session of an onnx.ModelProto or a graph file, warnings silenced (the
    graph-rewrite tests build graphs the runtime would comment on)."""
    import onnx
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.log_severity_level = 3
    src = model_or_path.SerializeToString() if isinstance(model_or_path, onnx.ModelProto) else str(model_or_path)
    return ort.InferenceSession(src, so, providers=["CPUExecutionProvider"])


def smoke_model_folder(tmp_path: Path) -> Path:
    """A copy of the smoke models in tmp_path/models with an export.json as export writes one
    (config, pipeline, files): a folder for the tools that edit a model folder's metadata."""
    import shutil

    from raindrop_tools import contract as C

    d = tmp_path / "models"
    shutil.copytree(FIXTURE_MODELS, d)
    info = {"config": "smoke", "pipeline": {"threshold": 0.5, "dilation": 3}, "files": C.graph_files(d)}
    (d / C.EXPORT_INFO).write_text(json.dumps(info, indent=2) + "\n")
    return d
