"""The study's results on disk, written so that nothing finished is ever lost.

Each finished point is one JSON file `points/<point_id>.json`, written atomically as its record
arrives (a reader or a killed client never sees half of one); --resume reads which ids exist.
Per-task timings are appended one JSON line per task to `timings.jsonl` (a line cut short by a
kill is skipped on reading). The tidy table is assembled from the point files at the end.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from geometry.atomic import atomic_target


class ResultStore:
    def __init__(self, out: Path):
        self.out = Path(out)
        self.points_dir = self.out / "points"
        self.timings_path = self.out / "timings.jsonl"

    def exists(self) -> bool:
        return self.points_dir.is_dir() and any(self.points_dir.glob("*.json"))

    def open(self) -> None:
        self.points_dir.mkdir(parents=True, exist_ok=True)

    def done_ids(self) -> set[str]:
        return {p.stem for p in self.points_dir.glob("*.json")} if self.points_dir.is_dir() else set()

    def write_point(self, row: dict, run: int) -> None:
        path = self.points_dir / f"{row['point_id']}.json"
        with atomic_target(path) as tmp:
            tmp.write_text(json.dumps({"run": run, "row": _jsonable(row)}, sort_keys=True))

    def read_point(self, point_id: str) -> dict:
        stored = json.loads((self.points_dir / f"{point_id}.json").read_text())
        return {k: _from_json(v) for k, v in stored["row"].items()}

    def run_of(self, point_id: str) -> int:
        return json.loads((self.points_dir / f"{point_id}.json").read_text())["run"]

    def append_timing(self, record: dict) -> None:
        with open(self.timings_path, "a") as f:
            f.write(json.dumps(record) + "\n")

    def timings(self) -> list[dict]:
        if not self.timings_path.exists():
            return []
        out = []
        for line in self.timings_path.read_text().splitlines():
            try:
                out.append(json.loads(line))
            except ValueError:
                continue  # the last line of a killed run
        return out

    def start_run(self, points_to_run: int) -> int:
        """Number this run (1, 2, ... in `runs.jsonl`) and record how many points it set out to run."""
        path = self.out / "runs.jsonl"
        run = 1 + (len(path.read_text().splitlines()) if path.exists() else 0)
        with open(path, "a") as f:
            f.write(json.dumps({"run": run, "points_to_run": points_to_run}) + "\n")
        return run


def _jsonable(row: dict) -> dict:
    """JSON has no NaN or infinity: store them as strings, read back as floats."""
    return {k: (repr(v) if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}


def _from_json(value):
    return float(value) if value in ("nan", "inf", "-inf") else value


def write_table(rows: list[dict], columns: list[str], parquet_path: Path, csv_path: Path) -> None:
    """The tidy table as Parquet (typed columns) and CSV, each written atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([{c: r.get(c) for c in columns} for r in rows], schema=_schema(rows, columns))
    with atomic_target(parquet_path) as tmp:
        pq.write_table(table, tmp)
    write_csv(rows, columns, csv_path)


def write_csv(rows: list[dict], columns: list[str], path: Path) -> None:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([["" if r.get(c) is None else r.get(c) for c in columns] for r in rows])
    with atomic_target(path) as tmp:
        tmp.write_text(buf.getvalue())


def _schema(rows: list[dict], columns: list[str]):
    """Column types from the values (a float column may hold NaN; a bool column may be null)."""
    import pyarrow as pa

    def kind(column):
        values = [r.get(column) for r in rows if r.get(column) is not None]
        if values and all(isinstance(v, bool) for v in values):
            return pa.bool_()
        if values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            return pa.int64()
        if values and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            return pa.float64()
        return pa.string()

    return pa.schema([(c, kind(c)) for c in columns])
