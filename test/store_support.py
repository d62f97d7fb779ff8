"""What the database tests share: the whole content of a results database, to compare runs."""

from __future__ import annotations

import sqlite3
from pathlib import Path

from dispeval_ros.io.store import RESULTS_FILE


def dump(directory: Path) -> dict[str, object]:
    """Everything in the database: schema, header marks and all rows, ordered."""
    db = sqlite3.connect(directory / RESULTS_FILE)
    try:
        content: dict[str, object] = {
            "schema": db.execute(
                "SELECT type, name, sql FROM sqlite_master ORDER BY name"
            ).fetchall(),
            "application_id": db.execute("PRAGMA application_id").fetchone(),
            "user_version": db.execute("PRAGMA user_version").fetchone(),
        }
        tables = [row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type='table'")]
        for table in tables:
            columns = [f'"{row[1]}"' for row in db.execute(f'PRAGMA table_info("{table}")')]
            content[table] = db.execute(
                f'SELECT * FROM "{table}" ORDER BY {", ".join(columns)}'
            ).fetchall()
        return content
    finally:
        db.close()


def units_stored(folder: Path) -> int:
    """How many units a (possibly running, or killed) run has written; 0 before its database."""
    try:
        db = sqlite3.connect(f"file:{folder / RESULTS_FILE}?mode=ro", uri=True)
    except sqlite3.Error:
        return 0
    try:
        return int(db.execute("SELECT COUNT(*) FROM units").fetchone()[0])
    except sqlite3.Error:
        return 0
    finally:
        db.close()
