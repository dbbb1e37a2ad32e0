"""The command line's outputs on the README's examples, normalised and digested.

    python benchmarks/result_digests.py            # run the commands, compare with the record
    python benchmarks/result_digests.py --record   # run them and write the record
    python benchmarks/result_digests.py --keep DIR # also keep the outputs in DIR

The commands (in a temporary folder, so every path in the outputs is the same on every machine):
``simulate`` and ``export-mdp`` as the README's "Command line" section runs them, ``infer`` with the
default (an adaptive set), with a named set and ``--per-action`` on the MDP archive, with
``--method map``, with ``--method birl`` (a short chain), with ``--expertise changing``; ``demo``
(seed 0); and ``study`` on a manifest of two people on ``crossroads`` (the README's demonstrations
and a noisier person's). Every JSON, CSV and Markdown file they write is read back and normalised:
what measures time (``run_time_s``, ``seconds``, a study's ``created``), the package
``version`` and the result's ``schema`` version are dropped, and the rest is written as sorted,
compact JSON; its SHA-256 is the file's digest. The record,
``benchmarks/results/result_digests.json``, holds the digests; a run that differs names each file
whose digest changed (with ``--against`` a folder kept earlier, the first key that differs) and
exits 1.

Floats are compared exactly (the commands are deterministic on one machine; a different CPU or
JAX version may change the last bits of some, and the record is then re-taken there).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
RECORD = HERE / "results" / "result_digests.json"

#: The commands, in order; each is the expertise-irl command line's arguments.
COMMANDS: list[list[str]] = [
    ["simulate", "crossroads", "--theta", "0.5,0.5,0,0,0", "--beta", "0.5", "--episodes", "20",
     "--seed", "1", "--out", "demos.csv"],
    ["simulate", "crossroads", "--theta", "0.2,0.5,0.3,0,0", "--beta", "1", "--episodes", "10",
     "--seed", "2", "--out", "demos2.csv"],
    ["export-mdp", "crossroads", "--out", "task.npz"],
    ["infer", "crossroads", "--demos", "demos.csv", "--out", "result.json"],
    ["infer", "--mdp", "task.npz", "--demos", "demos.csv", "--thetas", "0,0.5,1", "--betas",
     "0.1,1,10", "--per-action", "--out", "trace.json"],
    ["infer", "crossroads", "--demos", "demos.csv", "--method", "map", "--out", "map.json"],
    ["infer", "crossroads", "--demos", "demos.csv", "--method", "birl", "--iterations", "300",
     "--out", "birl.json"],
    ["infer", "crossroads", "--demos", "demos.csv", "--expertise", "changing", "--out", "curve.json"],
    ["demo", "--out", "demo"],
    ["study", "manifest.csv", "--out", "study", "--figures", "none"],
]

MANIFEST = "participant,map,demos\nP1,crossroads,demos.csv\nP2,crossroads,demos2.csv\n"

#: Keys that measure time or name the package's version, dropped wherever they appear.
TIMING_KEYS = frozenset({"version", "schema", "run_time_s", "seconds", "created"})


def normalise(doc):
    """``doc`` without the keys of :data:`TIMING_KEYS`, at any depth."""
    if isinstance(doc, dict):
        return {k: normalise(v) for k, v in doc.items() if k not in TIMING_KEYS}
    if isinstance(doc, list):
        return [normalise(v) for v in doc]
    return doc


def read_normalised(path: Path):
    """A file's content as a JSON value: a JSON file normalised, a CSV's rows, a text's lines."""
    if path.suffix == ".json":
        return normalise(json.loads(path.read_text(encoding="utf-8")))
    if path.suffix == ".csv":
        with open(path, encoding="utf-8", newline="") as fh:
            return list(csv.reader(fh))
    return path.read_text(encoding="utf-8").splitlines()


def digest(value) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def outputs(folder: Path) -> dict[str, Path]:
    """The files compared: JSON, CSV and Markdown, outside a study's engine folder."""
    return {p.relative_to(folder).as_posix(): p for p in sorted(folder.rglob("*"))
            if p.is_file() and p.suffix in (".json", ".csv", ".md") and "engine" not in p.parts}


def run_commands(folder: Path) -> None:
    exe = shutil.which("expertise-irl", path=str(Path(sys.executable).parent)) or "expertise-irl"
    (folder / "manifest.csv").write_text(MANIFEST, encoding="utf-8")
    for args in COMMANDS:
        done = subprocess.run([exe, *args], cwd=folder, capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"expertise-irl {' '.join(args)} failed ({done.returncode}):\n{done.stderr}")


def first_difference(a, b, where: str = "") -> str:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{where}.{k} only in {'the record' if k in a else 'this run'}"
            if a[k] != b[k]:
                return first_difference(a[k], b[k], f"{where}.{k}")
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{where}: {len(a)} items against {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            if x != y:
                return first_difference(x, y, f"{where}[{i}]")
    return f"{where}: {a!r:.80} against {b!r:.80}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--record", action="store_true", help="write the record instead of comparing")
    ap.add_argument("--keep", type=Path, help="copy the outputs to this folder")
    ap.add_argument("--against", type=Path,
                    help="a folder kept by --keep: name the first key that differs from its files")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        run_commands(folder)
        files = outputs(folder)
        values = {name: read_normalised(p) for name, p in files.items()}
        digests = {name: digest(v) for name, v in values.items()}
        if args.keep is not None:
            shutil.copytree(folder, args.keep, dirs_exist_ok=True)
        if args.record:
            RECORD.parent.mkdir(exist_ok=True)
            RECORD.write_text(json.dumps({"commands": COMMANDS, "digests": digests}, indent=1) + "\n",
                              encoding="utf-8")
            print(f"wrote {RECORD.relative_to(HERE.parent)}: {len(digests)} files")
            return 0
        record = json.loads(RECORD.read_text(encoding="utf-8"))["digests"]
        bad = 0
        for name in sorted(set(record) | set(digests)):
            if record.get(name) == digests.get(name):
                continue
            bad += 1
            if name not in digests or name not in record:
                print(f"{name}: {'missing from this run' if name in record else 'not in the record'}")
            elif args.against is not None and (args.against / name).is_file():
                print(f"{name}: {first_difference(read_normalised(args.against / name), values[name])}")
            else:
                print(f"{name}: digest differs")
        print(f"{len(digests) - bad} of {len(set(record) | set(digests))} files as recorded")
        return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
