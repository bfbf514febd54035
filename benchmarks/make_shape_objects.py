"""Write the shape-class benchmark's object specification files.

``benchmarks/objects/<class>/<name>.yaml`` for every object of
:func:`push_core.procedural.benchmark_objects` (seed 0): discs, ellipses, regular polygons,
rectangles, L, U and T shapes, crosses, other non-convex polygons and ``com_edge`` (COM 80-90 %
of the way from the centroid to the outline). The files are committed; ``benchmarks/
eval_shapes.py`` evaluates them. YAML files in the output directory that the set no longer
holds are removed (the directory belongs to this script).

Usage::

    .venv/bin/python benchmarks/make_shape_objects.py [--seed 0] [--out benchmarks/objects]
        [--check]

``--check`` writes nothing and exits 1 when the files differ from what would be written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from push_core.procedural import benchmark_objects

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "objects"


def render(spec: dict, cls: str, seed: int) -> str:
    """The YAML text of one spec file: a comment naming its origin, then the spec."""
    head = (f"# Shape-class benchmark object, class {cls}. Written by\n"
            f"# benchmarks/make_shape_objects.py --seed {seed} (push_core.procedural); "
            "do not edit.\n")
    return head + yaml.safe_dump(spec, sort_keys=False, default_flow_style=None, width=100)


def files(seed: int, out: Path) -> dict[Path, str]:
    """Path -> text of every spec file of the set."""
    return {out / cls / f"{spec['name']}.yaml": render(spec, cls, seed)
            for cls, specs in benchmark_objects(seed).items() for spec in specs}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--check", action="store_true",
                    help="compare with the files on disk instead of writing")
    args = ap.parse_args(argv)
    wanted = files(args.seed, args.out)
    stale = [p for p in args.out.glob("*/*.yaml") if p not in wanted]
    changed = [p for p, text in wanted.items()
               if not p.is_file() or p.read_text(encoding="utf-8") != text]
    if args.check:
        for p in changed + stale:
            print(f"differs: {p}")
        return 1 if changed or stale else 0
    for p in stale:
        p.unlink()
    for p in changed:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(wanted[p], encoding="utf-8")
    print(f"{len(wanted)} spec files in {args.out} ({len(changed)} written, {len(stale)} "
          "removed)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
