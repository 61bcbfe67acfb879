"""The reply cache's SQLite file: the schema, reads, writes and merges.

The store is one SQLite file in WAL mode, opened per operation with short transactions, which
is safe for several processes (parallel trials) sharing it; its keys are
:mod:`stalm.llm.cache_keys`' (re-exported here), and rows keyed the older way have no
``identity``.

The file carries stalm's SQLite ``application_id``. A path may come from a user who mistyped
it: an existing file that is neither marked so nor holds only stalm's own tables (another
program's database, a file that is not SQLite) is refused before anything touches it.

Kept apart from the policy module (the modes, which samples to ask the model for, what a
served reply counts as having cost) because this is the file format other people receive: a
cache file written by an older stalm (without ``call_seconds`` or ``identity``) still reads,
merges and upgrades in place.
"""

from __future__ import annotations

import os
import sqlite3
import time
import urllib.parse
from collections.abc import Iterable, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path

from stalm.cache_dir import stalm_cache_dir
from stalm.errors import StalmError
from stalm.llm.backends.base import LLMReply, LLMRequest
from stalm.llm.cache_keys import KEY_VERSION, legacy_sample_key, prompt_digest, sample_key

__all__ = [
    "CACHE_FILE_NAME",
    "STALM_APPLICATION_ID",
    "CachedSample",
    "ReplyCache",
    "check_reply_cache_file",
    "default_cache_path",
    "legacy_sample_key",
    "prompt_digest",
    "sample_key",
]

CACHE_FILE_NAME = "replies.sqlite"
STALM_APPLICATION_ID = 0x53544C4D
"""``PRAGMA application_id`` of a stalm reply cache ('STLM')."""
_OWN_TABLES = frozenset({"meta", "prompts", "replies"})
_BUSY_TIMEOUT_S = 30.0

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS prompts (
    prompt_sha TEXT PRIMARY KEY,
    system TEXT NOT NULL,
    user TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS replies (
    key TEXT PRIMARY KEY,
    backend TEXT NOT NULL,
    model TEXT NOT NULL,
    prompt_sha TEXT NOT NULL,
    temperature REAL NOT NULL,
    max_tokens INTEGER NOT NULL,
    seed INTEGER,
    constraint_fingerprint TEXT,
    sample_index INTEGER NOT NULL,
    text TEXT NOT NULL,
    prompt_tokens INTEGER NOT NULL,
    completion_tokens INTEGER NOT NULL,
    latency_s REAL NOT NULL,
    finish_reason TEXT,
    created_at REAL NOT NULL,
    call_seconds REAL,
    identity TEXT
);
"""
_COLUMNS_V1 = (
    "key, backend, model, prompt_sha, temperature, max_tokens, seed, constraint_fingerprint, "
    "sample_index, text, prompt_tokens, completion_tokens, latency_s, finish_reason, created_at"
)
"""The columns of a cache file written before ``call_seconds`` was added, in order."""


def default_cache_path() -> Path:
    """``$STALM_CACHE_DIR/replies.sqlite``, else ``~/.cache/stalm/replies.sqlite``."""
    return stalm_cache_dir() / CACHE_FILE_NAME


def check_reply_cache_file(path: Path) -> None:
    """A StalmError if ``path`` exists and is not a stalm reply cache; reads only.

    A missing or empty file, one marked with :data:`STALM_APPLICATION_ID`, and an unmarked
    one holding no tables but stalm's (written before the marker) are stalm's to use.
    """
    if not path.exists():
        return
    refused = f"{path} is not a stalm reply cache"
    if not path.is_file():
        raise StalmError(f"{refused} (not a regular file); name another file")
    if path.stat().st_size == 0:
        return
    try:
        uri = f"{path.resolve().as_uri()}?mode=ro"
        with closing(sqlite3.connect(uri, uri=True, timeout=_BUSY_TIMEOUT_S)) as conn:
            (application_id,) = conn.execute("PRAGMA application_id").fetchone()
            rows = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
            tables = {row[0] for row in rows if not row[0].startswith("sqlite_")}
    except (OSError, sqlite3.Error):
        raise StalmError(f"{refused} (not an SQLite database); name another file") from None
    if application_id == STALM_APPLICATION_ID:
        return
    if application_id == 0 and tables <= _OWN_TABLES:
        return
    raise StalmError(f"{refused} (it holds another program's tables); stalm leaves it alone")


@dataclass(frozen=True)
class CachedSample:
    """A reply ready to store, with the request fields kept for people inspecting the file.

    ``call_seconds`` is the reply's share of the wall time of the call that produced it
    (None when unknown: the reply's ``latency_s`` then stands in when it is read back).
    """

    key: str
    backend: str
    model: str
    request: LLMRequest
    index: int
    reply: LLMReply
    call_seconds: float | None = None
    identity: str | None = None
    """Whose backend made the reply (None: from an older stalm, which did not say)."""


@dataclass(frozen=True)
class StoredReply:
    """A cached reply and the seconds producing it took (see :class:`CachedSample`)."""

    reply: LLMReply
    call_seconds: float


class ReplyCache:
    """The SQLite file of cached replies.

    A connection is opened for each operation and closed after it, so the object holds no
    open handle (it can be passed to worker processes) and the write-ahead log is folded back
    into the main file when the last user closes it, leaving one self-contained file to send.
    """

    def __init__(
        self, path: str | os.PathLike[str] | None = None, *, read_only: bool = False
    ) -> None:
        self._path = Path(path).expanduser() if path is not None else default_cache_path()
        self._read_only = read_only
        self._uri: str | None = None
        """How a read-only cache is opened (an SQLite URI); None: the path, read-write."""
        self._has_call_seconds = True
        if read_only:
            self._open_read_only()
            return
        check_reply_cache_file(self._path)  # another program's file is never touched
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
            with self._connect() as conn:
                conn.execute(f"PRAGMA application_id={STALM_APPLICATION_ID}")
                conn.execute("PRAGMA journal_mode=WAL")
                conn.executescript(_SCHEMA)
                _add_columns(conn)
                conn.execute(
                    "INSERT OR REPLACE INTO meta(name, value) VALUES ('key_version', ?)",
                    (str(KEY_VERSION),),
                )
        except (OSError, sqlite3.Error) as error:
            raise StalmError(f"cannot open the reply cache {self._path}: {error}") from error

    def _open_read_only(self) -> None:
        """Open the file for reading only (replay): nothing is created, upgraded or written,
        so a cache on a read-only medium or in a folder the user may not write replays.

        ``mode=ro`` still needs the write-ahead log's shared-memory file beside the database,
        which a read-only folder cannot hold; then the file is read as ``immutable`` (nobody
        can be writing it where nobody may write)."""
        if not self._path.is_file():
            raise StalmError(
                f"no reply cache to replay at {self._path} (to ask a model instead, name it "
                "with --llm and leave the cache mode at 'use')"
            )
        base = "file:" + urllib.parse.quote(str(self._path.absolute()))
        failure: sqlite3.Error | None = None
        for query in ("?mode=ro", "?mode=ro&immutable=1"):
            self._uri = base + query
            try:
                with self._connect() as conn:
                    self._has_call_seconds = "call_seconds" in _columns(conn, "main")
                    conn.execute("SELECT COUNT(*) FROM replies").fetchone()
                return
            except sqlite3.Error as error:
                failure = error
        raise StalmError(f"cannot read the reply cache {self._path}: {failure}") from None

    @property
    def path(self) -> Path:
        return self._path

    @property
    def read_only(self) -> bool:
        return self._read_only

    def _open(self) -> sqlite3.Connection:
        if self._uri is not None:
            return sqlite3.connect(self._uri, uri=True, timeout=_BUSY_TIMEOUT_S)
        return sqlite3.connect(self._path, timeout=_BUSY_TIMEOUT_S)

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        with closing(self._open()) as conn:
            if not self._read_only:
                conn.execute("PRAGMA synchronous=NORMAL")
            with conn:  # one short transaction, committed on success
                yield conn

    def get_many(self, keys: Iterable[str]) -> dict[str, LLMReply]:
        """The stored replies among ``keys`` (missing keys are simply absent)."""
        return {key: stored.reply for key, stored in self.get_stored(keys).items()}

    def get_stored(self, keys: Iterable[str]) -> dict[str, StoredReply]:
        """The stored replies among ``keys`` with the seconds producing each took."""
        wanted = list(dict.fromkeys(keys))
        if not wanted:
            return {}
        found: dict[str, StoredReply] = {}
        # a read-only file from before call_seconds cannot gain the column: read it as NULL
        call = "call_seconds" if self._has_call_seconds else "NULL"
        try:
            with self._connect() as conn:
                for start in range(0, len(wanted), 500):
                    chunk = wanted[start : start + 500]
                    marks = ",".join("?" * len(chunk))
                    rows = conn.execute(
                        "SELECT key, text, prompt_tokens, completion_tokens, latency_s, "
                        f"finish_reason, {call} FROM replies WHERE key IN ({marks})",
                        chunk,
                    )
                    for row in rows:
                        key, text, prompt_tokens, completion_tokens, latency, finish, call = row
                        reply = LLMReply(
                            text=text,
                            prompt_tokens=prompt_tokens,
                            completion_tokens=completion_tokens,
                            latency_s=latency,
                            finish_reason=finish,
                        )
                        found[key] = StoredReply(reply, latency if call is None else call)
        except sqlite3.Error as error:
            raise StalmError(f"cannot read the reply cache {self._path}: {error}") from error
        return found

    def put_many(self, samples: Iterable[CachedSample]) -> None:
        """Store (or overwrite) replies in one short transaction."""
        rows = []
        prompts = {}
        now = time.time()
        for sample in samples:
            request, reply = sample.request, sample.reply
            sha = prompt_digest(request.system, request.user)
            prompts[sha] = (sha, request.system, request.user)
            rows.append(
                (
                    sample.key,
                    sample.backend,
                    sample.model,
                    sha,
                    request.temperature,
                    request.max_tokens,
                    request.seed,
                    request.constraint.fingerprint if request.constraint else None,
                    sample.index,
                    reply.text,
                    reply.prompt_tokens,
                    reply.completion_tokens,
                    reply.latency_s,
                    reply.finish_reason,
                    now,
                    sample.call_seconds,
                    sample.identity,
                )
            )
        if not rows:
            return
        if self._read_only:
            raise StalmError(f"the reply cache {self._path} was opened read-only (replay)")
        try:
            with self._connect() as conn:
                conn.executemany(
                    "INSERT OR IGNORE INTO prompts(prompt_sha, system, user) VALUES (?, ?, ?)",
                    list(prompts.values()),
                )
                conn.executemany(
                    f"INSERT OR REPLACE INTO replies ({_COLUMNS_V1}, call_seconds, identity) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    rows,
                )
        except sqlite3.Error as error:
            raise StalmError(f"cannot write the reply cache {self._path}: {error}") from error

    def __len__(self) -> int:
        with self._connect() as conn:
            (count,) = conn.execute("SELECT COUNT(*) FROM replies").fetchone()
        return int(count)

    def merge_from(self, other: str | os.PathLike[str]) -> int:
        """Add every reply of the cache file ``other`` that this cache lacks; return how many.

        How replies made on other machines (Ray workers) come home: stored replies are never
        overwritten, so merging is idempotent and order-free.
        """
        source = Path(other)
        if not source.is_file():
            raise StalmError(f"no reply cache to merge at {source}")
        before = len(self)
        try:
            with self._connect() as conn:
                conn.execute("ATTACH DATABASE ? AS other", (str(source),))
                conn.execute("INSERT OR IGNORE INTO prompts SELECT * FROM other.prompts")
                # a file written before call_seconds or identity existed lacks the column:
                # it stays NULL
                theirs = _columns(conn, "other")
                columns = ", ".join(
                    [_COLUMNS_V1, *(c for c in ("call_seconds", "identity") if c in theirs)]
                )
                conn.execute(
                    f"INSERT OR IGNORE INTO replies ({columns}) SELECT {columns} FROM other.replies"
                )
        except sqlite3.Error as error:
            raise StalmError(f"cannot merge the reply cache {source}: {error}") from error
        return len(self) - before

    def export(self, destination: str | os.PathLike[str]) -> Path:
        """Copy the cache into one consistent file (safe while others write) to send along."""
        target = Path(destination).expanduser()
        check_reply_cache_file(target)  # a backup overwrites: never another program's file
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            with (
                closing(self._open()) as source,
                closing(sqlite3.connect(target)) as sink,
            ):
                source.backup(sink)
        except sqlite3.Error as error:
            raise StalmError(f"cannot export the reply cache to {target}: {error}") from error
        return target


def _add_columns(conn: sqlite3.Connection) -> None:
    """Give a cache file written before ``call_seconds`` or ``identity`` existed the column
    (NULL in old rows). Another process may add it at the same moment; its "duplicate column"
    is no error."""
    present = _columns(conn, "main")
    for column, kind in (("call_seconds", "REAL"), ("identity", "TEXT")):
        if column in present:
            continue
        try:
            conn.execute(f"ALTER TABLE replies ADD COLUMN {column} {kind}")
        except sqlite3.OperationalError as error:
            if "duplicate column" not in str(error):
                raise


def _columns(conn: sqlite3.Connection, schema: str) -> set[str]:
    """The column names of the ``replies`` table in the attached database ``schema``."""
    return {row[1] for row in conn.execute(f"PRAGMA {schema}.table_info(replies)")}
