"""Start-up: wall time of `robustsynth --help`, `schema`, `build-model` against
`python -c "import numpy"`, measured side by side in one run (median of N repetitions)."""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPEAT = 7


def _time(cmd: list[str]) -> float:
    samples = []
    for _ in range(REPEAT):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def main() -> dict[str, float]:
    exe = [sys.executable, "-m", "robustsynth"]
    with tempfile.TemporaryDirectory() as tmp:
        cases = {
            'python -c "import numpy"': [sys.executable, "-c", "import numpy"],
            "robustsynth --help": exe + ["--help"],
            "robustsynth schema": exe + ["schema"],
            "robustsynth build-model": exe + ["build-model", "-o", str(Path(tmp) / "m")],
        }
        times = {name: _time(cmd) for name, cmd in cases.items()}
    base = times['python -c "import numpy"']
    print(f"start-up (median of {REPEAT}, wall time)")
    for name, t in times.items():
        print(f"  {name:28s} {t * 1000:8.1f} ms   ratio to import numpy: {t / base:5.2f}")
    return times


if __name__ == "__main__":
    main()
