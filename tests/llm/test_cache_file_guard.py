"""A file that is not stalm's reply cache is refused, never altered (issue 30, item 2): an
existing SQLite file without stalm's marker and with tables of its own, or a file that is not
SQLite at all, is one error line and stays byte for byte what it was."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from stalm.errors import StalmError
from stalm.llm.cache_file import STALM_APPLICATION_ID, ReplyCache

pytestmark = pytest.mark.usefixtures("clean_llm_env")


def other_application_db(path: Path) -> bytes:
    """Another program's SQLite database (rollback journal, a table of its own)."""
    with sqlite3.connect(path) as conn:
        conn.execute("CREATE TABLE users (id INTEGER PRIMARY KEY, name TEXT)")
        conn.execute("INSERT INTO users(name) VALUES ('ada')")
    conn.close()
    return path.read_bytes()


def test_another_programs_database_is_refused_and_left_alone(tmp_path: Path) -> None:
    path = tmp_path / "app.db"
    before = other_application_db(path)
    with pytest.raises(StalmError) as caught:
        ReplyCache(path)
    message = str(caught.value)
    assert "\n" not in message and "not a stalm reply cache" in message and str(path) in message
    assert "ada" not in message
    assert path.read_bytes() == before, "not one byte changed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["app.db"], "no -wal or -shm beside it"
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
        tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master")}
    assert tables == {"users"}


def test_a_file_that_is_not_sqlite_is_refused_and_left_alone(tmp_path: Path) -> None:
    path = tmp_path / "notes.txt"
    path.write_text("my notes, not a database\n" * 50)
    before = path.read_bytes()
    with pytest.raises(StalmError, match="not a stalm reply cache"):
        ReplyCache(path)
    assert path.read_bytes() == before


def test_exporting_over_another_programs_database_is_refused(tmp_path: Path) -> None:
    cache = ReplyCache(tmp_path / "replies.sqlite")
    target = tmp_path / "app.db"
    before = other_application_db(target)
    with pytest.raises(StalmError, match="not a stalm reply cache"):
        cache.export(target)
    assert target.read_bytes() == before


def test_a_new_cache_carries_stalms_marker_and_an_old_one_gains_it(tmp_path: Path) -> None:
    fresh = ReplyCache(tmp_path / "new.sqlite").path
    with sqlite3.connect(fresh) as conn:
        assert conn.execute("PRAGMA application_id").fetchone()[0] == STALM_APPLICATION_ID
    old = tmp_path / "old.sqlite"  # what stalm wrote before the marker: its three tables
    with sqlite3.connect(old) as conn:
        conn.executescript(
            "CREATE TABLE meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);"
            "INSERT INTO meta VALUES ('key_version', '1');"
            "CREATE TABLE prompts (prompt_sha TEXT PRIMARY KEY, system TEXT, user TEXT);"
        )
    conn.close()
    ReplyCache(old)
    with sqlite3.connect(old) as conn:
        assert conn.execute("PRAGMA application_id").fetchone()[0] == STALM_APPLICATION_ID


def test_an_empty_file_becomes_a_cache(tmp_path: Path) -> None:
    path = tmp_path / "empty.sqlite"
    path.touch()
    assert len(ReplyCache(path)) == 0
