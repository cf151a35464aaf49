"""Decoder of the committed SICK MRS1104 capture (``tests/data/real/mrs1104_sick_scan_xd.json.gz``),
for the tests only: the capture is sick_scan_xd's emulator format (a JSON list of the TCP
payloads of a recorded session, hex), whose scan telegrams are SOPAS CoLa-B ``sSN LMDscandata``,
one layer each. Layout after SICK's telegram listing, as sick_scan_xd's parser reads it
(``parseCommonBinaryResultTelegram``): all big-endian; the layer angle at byte 50 (int16, the
elevation is minus it in 1/100 deg on the MRS1000 family), then the scan and measurement
frequencies, the encoders, and per 16-bit channel its name, scale, offset, start angle and step
(1/10000 deg) and ranges (mm); azimuths are the device's minus 90 deg (sick_scan_xd's
``ScanAngleShift`` for the MRS1xxx). A telegram ends with an XOR checksum of its body.
"""

from __future__ import annotations

import gzip
import json
import struct
from pathlib import Path

import numpy as np

CAPTURE = Path(__file__).parent / "data" / "real" / "mrs1104_sick_scan_xd.json.gz"
SCAN_TELEGRAM = b"sSN LMDscandata "
LAYER_ANGLE_AT = 50  # byte offset of the int16 layer angle
AZIMUTH_SHIFT_DEG = -90.0  # device angle -> sensor frame (x forward)


def scan_telegrams(path: Path = CAPTURE) -> list[bytes]:
    """The capture's scan telegrams in order, each checked (framing, length, checksum)."""
    with gzip.open(path, "rt") as f:
        entries = json.load(f)
    telegrams = []
    for entry in entries:
        payload = bytes.fromhex(entry["_source"]["layers"]["tcp"]["tcp.payload"].replace(":", ""))
        if payload[8:24] != SCAN_TELEGRAM:
            continue  # the driver's start-up exchange
        (length,) = struct.unpack_from(">I", payload, 4)
        assert payload[:4] == b"\x02" * 4 and len(payload) == 8 + length + 1
        assert np.bitwise_xor.reduce(np.frombuffer(payload[8:-1], dtype=np.uint8)) == payload[-1]
        telegrams.append(payload)
    return telegrams


def layer_points(telegram: bytes) -> tuple[float, np.ndarray, np.ndarray]:
    """One layer: its elevation [deg], and its beams' azimuths [deg] and ranges [m] (0 = none)."""
    (layer_angle,) = struct.unpack_from(">h", telegram, LAYER_ANGLE_AT)
    at = LAYER_ANGLE_AT + 2 + 8  # scan and measurement frequencies
    (n_encoders,) = struct.unpack_from(">H", telegram, at)
    at += 2 + 6 * n_encoders
    (n_channels,) = struct.unpack_from(">H", telegram, at)
    at += 2
    for _ in range(n_channels):
        name = telegram[at : at + 5]
        scale, offset, start, step, n = struct.unpack_from(">ffiHH", telegram, at + 5)
        at += 5 + 16
        values = np.frombuffer(telegram, dtype=">u2", count=n, offset=at).astype(np.float64)
        at += 2 * n
        if name == b"DIST1":
            azimuth = start / 1e4 + AZIMUTH_SHIFT_DEG + np.arange(n) * step / 1e4
            return -layer_angle / 100.0, azimuth, (values * scale + offset) / 1000.0
    raise ValueError("scan telegram without a DIST1 channel")


def clouds(frames: int, path: Path = CAPTURE) -> list[np.ndarray]:
    """The first ``frames`` 4-layer scans (four consecutive telegrams each) as a driver would
    publish them: float32 x, y, z in the sensor's ROS frame (x forward, y left, z up; sick_scan_xd's
    azimuth and elevation conventions), layer by layer (lowest first), each layer's beams in firing
    order, with the layer index as ``ring``; beams without a return left out."""
    telegrams = scan_telegrams(path)
    out = []
    for k in range(frames):
        layers = sorted(layer_points(t) for t in telegrams[4 * k : 4 * k + 4])
        parts = []
        for ring, (elevation, azimuth, ranges) in enumerate(layers):
            el, az, r = np.radians(elevation), np.radians(azimuth), ranges
            ok = r > 0
            part = np.zeros(int(ok.sum()), dtype=[(n, "<f4") for n in "xyz"] + [("ring", "<u2")])
            part["x"] = (r * np.cos(el) * np.cos(az))[ok]
            part["y"] = (r * np.cos(el) * np.sin(az))[ok]
            part["z"] = (r * np.sin(el))[ok]
            part["ring"] = ring
            parts.append(part)
        out.append(np.concatenate(parts))
    return out
