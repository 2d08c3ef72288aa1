"""Draw a synthetic head-IMU trace (stand, step in place, turn) with the true steps marked.

Usage: python examples/imu_trace.py [OUT_DIR]
"""

import sys
from pathlib import Path

from agents.experiments.imu_trace import run_imu_trace

if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out")
    print(f"wrote {run_imu_trace(out)}")
