#!/usr/bin/env python3
"""zxing-cpp (PyPI) decode + detect time on the speed benchmark's frames, for comparison
with `cargo bench --bench detect` on the very same JPEG bytes.

    QRPOSE_WRITE_FRAME=target/frame_1280x720.jpg cargo run --release --example detect_speed -- auto 1280x720 1
    taskset -c 0 python3 scripts/speed_zxing_pypi.py target/frame_1280x720.jpg

Decode: OpenCV `imdecode(..., IMREAD_GRAYSCALE)` (libjpeg-turbo); detect:
`zxingcpp.read_barcodes` with the library's default options (try harder, rotate, invert,
downscale), QR only. Prints the median over 50 runs after 5 warm-ups. Uses the venv of
scripts/accuracy_images.py (target/pyenv).
"""
import statistics, sys, time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from accuracy_images import ensure_venv  # noqa: E402


def main():
    ensure_venv()
    import cv2, numpy as np, zxingcpp
    for path in sys.argv[1:]:
        data = np.frombuffer(Path(path).read_bytes(), dtype=np.uint8)
        decode_ms, total_ms, found = [], [], 0
        for k in range(55):
            t0 = time.perf_counter()
            gray = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE)
            t1 = time.perf_counter()
            found = len(zxingcpp.read_barcodes(gray, formats=zxingcpp.BarcodeFormat.QRCode))
            t2 = time.perf_counter()
            if k >= 5:
                decode_ms.append(1e3 * (t1 - t0))
                total_ms.append(1e3 * (t2 - t0))
        print(f"{path}: codes {found}, decode {statistics.median(decode_ms):.2f} ms, "
              f"decode + detect {statistics.median(total_ms):.2f} ms (medians of 50)")


if __name__ == "__main__":
    main()
