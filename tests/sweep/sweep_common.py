"""Helpers of the sweep tests: the small envmap sweep (2 scenes x 2 methods, the cheapest oracle runs)."""

from __future__ import annotations

import csv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCENES = ("launch/scenes/red_wall.yaml", "launch/scenes/convex_room.yaml")
# the cheapest real envmap runs: ~2-5 s each on 2 cores
CHEAP = ["--oracle", "--duration", "0.5", "--stride", "4", "--face-size", "16", "--atlas-size", "64"]


def write_sweep(path: Path, scenes=SCENES, methods=("ours", "baseline"), extra: str = "") -> Path:
    """A sweep file of ``scenes`` x ``methods`` collecting each run's mean envmap PSNR and coverage."""
    args = ", ".join(['"{scene}"', *CHEAP, "--methods", '"{method}"'])
    path.write_text(f"""name: small
run:
  eval: envmap
  args: [{args}]
axes:
  scene: [{", ".join(str(ROOT / s) if not Path(s).is_absolute() else s for s in scenes)}]
  method: [{", ".join(methods)}]
resources: {{cpus: 1}}
collect:
  psnr: "{{method}}.*.envmap_psnr"
  coverage: "{{method}}.*.coverage"
report: {{rows: method, columns: scene}}
{extra}""")
    return path


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def values(rows: list[dict]) -> dict:
    """(scene, method) -> (status, psnr, coverage) of a results table."""
    return {(r["scene"], r["method"]): (r["status"], r["psnr"], r["coverage"]) for r in rows}
