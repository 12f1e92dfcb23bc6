"""Occupancy grids as ROS ``map_server`` files (YAML plus PGM or PNG) and PNG images
(thesis Sec. 7.6.1.1: the participant's 2D occupancy grid map).

Occupied cells are written 0 (black), free cells 254 (white); reading back, a pixel
is free when ``p < free_thresh`` with ``p = (255 - value) / 255`` (``negate: 0``; ``value
/ 255`` with ``negate: 1``), and occupied or unknown otherwise; ``mode: raw`` (Nav2)
reads the pixel as the occupancy in percent, values above 100 unknown, and ignores
``negate``. Images may be binary or plain PGM (8 or 16 bit) or 8-bit PNG; the map's
``origin`` yaw must be 0 (axis-aligned grids only).
"""

from __future__ import annotations

import math
import re
import struct
import zlib
from pathlib import Path

import numpy as np

from sim.occupancy import OccupancyGrid

FREE_VALUE = 254  # PGM/PNG pixel of a free cell (ROS map_saver)
OCCUPIED_VALUE = 0  # PGM/PNG pixel of an occupied cell


def _image_rows(grid: OccupancyGrid) -> np.ndarray:
    """(rows, cols) uint8 image, row 0 the top of the map (image convention)."""
    img = np.where(grid.occupied, OCCUPIED_VALUE, FREE_VALUE).astype(np.uint8)
    return img[::-1]


def save_ros_map(grid: OccupancyGrid, directory: str | Path, stem: str) -> tuple[Path, Path]:
    """Write the grid as a ROS ``map_server`` map: ``stem.pgm`` and ``stem.yaml``.

    Parameters
    ----------
    grid : OccupancyGrid
    directory : str or Path
        Created if missing.
    stem : str
        File name without extension.

    Returns
    -------
    (Path, Path)
        The PGM image (P5, 0 = occupied, 254 = free, first row the top of the map)
        and the YAML description, in that order.
    """
    directory = Path(directory)
    if stem in ("", ".", "..") or any(c in stem for c in "/\\\x00"):
        raise ValueError(f"map file name {stem!r}: must be one plain file name, no folder part")
    directory.mkdir(parents=True, exist_ok=True)
    pgm, yaml = directory / f"{stem}.pgm", directory / f"{stem}.yaml"
    img = _image_rows(grid)
    rows, cols = img.shape
    pgm.write_bytes(f"P5\n{cols} {rows}\n255\n".encode("ascii") + img.tobytes())
    yaml.write_text(
        f"image: {pgm.name}\n"
        f"resolution: {grid.resolution!r}\n"
        f"origin: [{grid.origin[0]!r}, {grid.origin[1]!r}, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n",
        encoding="utf-8",
    )
    return pgm, yaml


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def save_png(grid: OccupancyGrid, path: str | Path) -> Path:
    """Write the grid as an 8-bit greyscale PNG (0 = occupied, 254 = free, top row = max y).

    Readable by :func:`load_ros_map` when named in a map YAML.
    """
    path = Path(path)
    img = _image_rows(grid)
    rows, cols = img.shape
    raw = np.hstack((np.zeros((rows, 1), np.uint8), img)).tobytes()  # filter byte 0 per row
    header = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", zlib.compress(raw, 9))
        + _png_chunk(b"IEND", b"")
    )
    return path


def _read_pgm(data: bytes) -> np.ndarray:
    """PGM (P5 binary or P2 plain, 8 or 16 bit) -> (rows, cols) float in [0, 255]."""
    header = re.match(rb"(P[25])((?:\s+|#[^\n]*\n)+)", data)
    if header is None:
        raise ValueError("not a PGM image (P5 or P2)")
    tokens, pos = [], header.start(2)
    token_re = re.compile(rb"(?:\s|#[^\n]*(?:\n|$))*(\d+)")
    for _ in range(3):
        m = token_re.match(data, pos)
        if m is None:
            raise ValueError("PGM header must give width, height and maxval")
        tokens.append(int(m.group(1)))
        pos = m.end()
    cols, rows, maxval = tokens
    if cols < 1 or rows < 1 or not 1 <= maxval <= 65535:
        raise ValueError(f"bad PGM size {cols}x{rows} or maxval {maxval}")
    if header.group(1) == b"P2":
        values = np.array(data[pos:].split(), dtype=np.int64)
    else:
        pos += 1  # exactly one whitespace byte before the raster
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        values = np.frombuffer(data, dtype=dtype, count=-1, offset=pos)
    if values.size < rows * cols:
        raise ValueError(f"PGM raster holds {values.size} values, needs {rows * cols}")
    return values[: rows * cols].reshape(rows, cols).astype(float) * (255.0 / maxval)


def _unfilter_png(raw: bytes, rows: int, cols: int, bpp: int) -> np.ndarray:
    """Undo PNG's per-row filters (8-bit samples) -> (rows, cols * bpp) uint8."""
    stride = cols * bpp
    if len(raw) != rows * (stride + 1):
        raise ValueError("PNG image data has the wrong length")
    data = np.frombuffer(raw, dtype=np.uint8).reshape(rows, stride + 1)
    out = np.zeros((rows, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int64)
    for r in range(rows):
        kind, line = int(data[r, 0]), data[r, 1:].astype(np.int64)
        if kind == 0:
            cur = line
        elif kind == 1:  # Sub: cumulative sum per channel
            cur = np.cumsum(line.reshape(cols, bpp), axis=0).ravel() % 256
        elif kind == 2:  # Up
            cur = (line + prev) % 256
        elif kind in (3, 4):  # Average, Paeth: sequential along the row
            cur_l, line_l, prev_l = [0] * stride, line.tolist(), prev.tolist()
            for i in range(stride):
                a = cur_l[i - bpp] if i >= bpp else 0
                b = prev_l[i]
                if kind == 3:
                    cur_l[i] = (line_l[i] + (a + b) // 2) % 256
                else:
                    c = prev_l[i - bpp] if i >= bpp else 0
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                    cur_l[i] = (line_l[i] + pred) % 256
            cur = np.array(cur_l, dtype=np.int64)
        else:
            raise ValueError(f"unknown PNG filter type {kind}")
        out[r] = cur
        prev = cur
    return out


def _read_png(data: bytes) -> np.ndarray:
    """8-bit non-interlaced PNG (grey, RGB, grey+alpha, RGBA) -> (rows, cols) float in [0, 255].

    Colour is averaged over the colour channels; alpha is ignored.
    """
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError("not a PNG image")
    pos, idat, header = 8, [], None
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        chunk = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", chunk[:13])
        elif kind == b"IDAT":
            idat.append(chunk)
        elif kind == b"IEND":
            break
    if header is None or not idat:
        raise ValueError("PNG without IHDR or image data")
    cols, rows, depth, colour, _, _, interlace = header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(colour)
    if depth != 8 or channels is None or interlace != 0:
        raise ValueError(
            "only 8-bit, non-interlaced greyscale, RGB or RGBA PNG images are supported"
        )
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as error:
        raise ValueError(f"corrupt PNG image data: {error}") from None
    pixels = _unfilter_png(raw, rows, cols, channels).reshape(rows, cols, channels)
    n_colour = 1 if channels <= 2 else 3
    return pixels[:, :, :n_colour].astype(float).mean(axis=2)


_YAML_COMMENT = re.compile(r"(?:^|\s)#.*$")  # YAML: '#' starts a comment after a blank
_YAML_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


def _parse_map_yaml(path: Path) -> dict[str, str]:
    """The flat ``key: value`` lines of a ROS map YAML (values as text)."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file") from None
    fields: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = _YAML_COMMENT.sub("", line).strip()
        if not stripped or stripped == "---":
            continue
        key, sep, value = stripped.partition(":")
        key = key.strip().strip("'\"")
        if not sep or not key:
            raise ValueError(f"{path}: line {number}: expected 'key: value', got {line.strip()!r}")
        if key not in _YAML_KEYS:
            raise ValueError(
                f"{path}: field '{key}': is not a known field (known: {', '.join(_YAML_KEYS)})"
            )
        fields[key] = value.strip()
    return fields


def _yaml_number(path: Path, fields: dict[str, str], key: str, default: float | None) -> float:
    if key not in fields:
        if default is None:
            raise ValueError(f"{path}: field '{key}': is required")
        return default
    try:
        value = float(fields[key])
    except ValueError:
        raise ValueError(f"{path}: field '{key}': must be a number, got {fields[key]!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{path}: field '{key}': must be a finite number, got {fields[key]!r}")
    return value


def _origin(path: Path, fields: dict[str, str]) -> list[float]:
    """The map's ``origin`` [x [m], y [m], yaw [rad]]; the yaw must be 0."""
    origin_text = fields.get("origin")
    if origin_text is None:
        raise ValueError(f"{path}: field 'origin': is required, as [x, y, yaw]")
    m = re.fullmatch(r"\[([^\]]*)\]", origin_text)
    try:
        origin = [float(v) for v in m.group(1).split(",")] if m else []
    except ValueError:
        origin = []
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise ValueError(f"{path}: field 'origin': must be [x, y, yaw], got {origin_text!r}")
    if origin[2] != 0.0:
        raise ValueError(
            f"{path}: field 'origin': the yaw must be 0 (axis-aligned grids only), got {origin[2]}"
        )
    return origin


def load_ros_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a ROS ``map_server`` map (YAML plus PGM or PNG image) into a grid.

    Parameters
    ----------
    yaml_path : str or Path
        The YAML file; its ``image`` is relative to the YAML's directory unless absolute.

    Returns
    -------
    OccupancyGrid
        Occupied where ``p > occupied_thresh`` or unknown; free where ``p < free_thresh``.

    Raises
    ------
    ValueError
        Naming the file and the field, on any bad content.
    FileNotFoundError
        When the YAML file does not exist.
    """
    path = Path(yaml_path)
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    fields = _parse_map_yaml(path)

    if not fields.get("image"):
        raise ValueError(f"{path}: field 'image': is required (the map image's file name)")
    image = Path(fields["image"].strip("'\""))
    image = image if image.is_absolute() else path.parent / image

    resolution = _yaml_number(path, fields, "resolution", None)
    if resolution <= 0:
        raise ValueError(f"{path}: field 'resolution': must be positive, got {resolution}")

    origin = _origin(path, fields)

    negate = _yaml_number(path, fields, "negate", 0.0)
    if negate not in (0.0, 1.0):
        raise ValueError(f"{path}: field 'negate': must be 0 or 1, got {fields['negate']!r}")
    occupied_thresh = _yaml_number(path, fields, "occupied_thresh", 0.65)
    free_thresh = _yaml_number(path, fields, "free_thresh", 0.196)
    if not 0.0 <= free_thresh <= occupied_thresh <= 1.0:
        raise ValueError(
            f"{path}: field 'free_thresh': must satisfy 0 <= free_thresh <= occupied_thresh "
            f"<= 1, got {free_thresh} and {occupied_thresh}"
        )
    mode = fields.get("mode", "trinary").strip("'\"")
    if mode not in ("trinary", "scale", "raw"):
        raise ValueError(f"{path}: field 'mode': must be trinary, scale or raw, got {mode!r}")

    if not image.is_file():
        raise ValueError(f"{path}: field 'image': no such file {image}")
    data = image.read_bytes()
    try:
        pixels = _read_png(data) if data.startswith(b"\x89PNG") else _read_pgm(data)
    except ValueError as error:
        raise ValueError(f"{path}: field 'image': {image.name}: {error}") from None
    if mode == "raw":  # the pixel is the occupancy in percent, > 100 unknown (Nav2)
        p = np.where(pixels <= 100.0, np.round(pixels) / 100.0, 1.0)
    else:
        p = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    free = p < free_thresh
    return OccupancyGrid(~free[::-1].copy(), (origin[0], origin[1]), resolution)
