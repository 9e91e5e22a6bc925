"""Regenerate the README's pictures from the current code: `python docs/img/regenerate.py`.

It runs the demo the README shows — `mrta demo --seed 0` (patrol under ALLIANCE, robot2
crashing at 30 s), in lockstep at full speed, which gives the same run as at the default speed —
in a scratch folder and copies its pictures here:

    world.png                                  → demo_world.png
    timeline.png                               → demo_timeline.png
    motivation_robot3_border_protection.png    → demo_motivation_robot3_border_protection.png

One seed gives one run: the world and the timeline change only when the code's behaviour does
(they are the same, byte for byte, at any --speed). The motivation panels are drawn on the
recording's log times (ALLIANCE's plots), which follow the recorder's hearing: they may differ
in small details from one run to the next. Run it after a change that alters what the demo
does or draws, and commit the pictures.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
PICTURES = {
    "world.png": "demo_world.png",
    "timeline.png": "demo_timeline.png",
    "motivation_robot3_border_protection.png": "demo_motivation_robot3_border_protection.png",
}


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="mrta-img-") as tmp:
        out = Path(tmp) / "demo"
        cmd = [sys.executable, "-m", "mrta_zenoh.cli.main", "-q", "demo", "--seed", "0",
               "--speed", "0", "--output", str(out)]
        print("running:", " ".join(["mrta", *cmd[3:]]), flush=True)
        done = subprocess.run(cmd, cwd=ROOT)
        if done.returncode != 0:
            print(f"the demo failed (exit {done.returncode}); no picture changed",
                  file=sys.stderr)
            return done.returncode
        missing = [name for name in PICTURES if not (out / name).is_file()]
        if missing:
            print(f"the demo wrote no {', '.join(missing)}; no picture changed", file=sys.stderr)
            return 1
        for name, target in PICTURES.items():
            new, old = (out / name).read_bytes(), HERE / target
            same = old.is_file() and old.read_bytes() == new
            if not same:
                shutil.copyfile(out / name, old)
            print(f"{target}: {'unchanged' if same else 'updated'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
