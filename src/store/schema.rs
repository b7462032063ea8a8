//! The database schema as an append-only list of migrations. Never edit a migration that
//! has shipped: add a new one. `PRAGMA user_version` holds the version applied (it sits at
//! a fixed offset in the file header, so any tool can read it), and `schema_migrations`
//! keeps the audit trail of when each was applied and by which version of scanmill.

/// Migration `i` brings the schema from version `i` to `i + 1`.
pub const MIGRATIONS: &[&str] = &[V1, V2, V3, V4];

/// The newest schema version this binary knows.
pub const LATEST: u32 = MIGRATIONS.len() as u32;

/// Times are Unix milliseconds (INTEGER). Hashes are lowercase hex SHA-256.
const V1: &str = r#"
CREATE TABLE schema_migrations (
    version     INTEGER PRIMARY KEY,
    applied_at  INTEGER NOT NULL,
    app_version TEXT NOT NULL
) STRICT;

-- One row per (input content, recipe): the queue entry and the audit record together.
CREATE TABLE job (
    id           INTEGER PRIMARY KEY,
    job_key      TEXT NOT NULL UNIQUE,        -- sha256(set_hash, recipe_hash)
    set_hash     TEXT NOT NULL,               -- content of the whole input set
    root         TEXT NOT NULL,               -- watched folder (absolute)
    rel_path     TEXT NOT NULL,               -- the scan's mesh file, relative to root
    output_root  TEXT NOT NULL,
    recipe_path  TEXT NOT NULL,
    recipe_hash  TEXT NOT NULL,
    recipe_json  TEXT NOT NULL,               -- the resolved recipe
    config_hash  TEXT NOT NULL,
    state        TEXT NOT NULL CHECK (state IN ('queued','running','done','failed','quarantined')),
    retryable    INTEGER NOT NULL DEFAULT 0,  -- a failed job that will be tried again at run_after
    attempts     INTEGER NOT NULL DEFAULT 0,  -- counted attempts (interruptions are not counted)
    max_attempts INTEGER NOT NULL,
    generation   INTEGER NOT NULL DEFAULT 0,  -- bumped by `requeue`; part of publish idempotency
    run_after    INTEGER NOT NULL,
    created_at   INTEGER NOT NULL,
    updated_at   INTEGER NOT NULL,
    started_at   INTEGER,
    finished_at  INTEGER,
    lease_owner  TEXT,
    host         TEXT,
    app_version  TEXT,
    output_dir   TEXT,
    error_kind   TEXT,
    error        TEXT,
    in_vertices  INTEGER,
    in_faces     INTEGER,
    out_vertices INTEGER,
    out_faces    INTEGER,
    process_ms   REAL,
    report_json  TEXT                          -- the full processing report, metrics included
) STRICT;
CREATE INDEX job_claimable ON job(run_after, id) WHERE state IN ('queued', 'failed');
CREATE INDEX job_state_finished ON job(state, finished_at);
CREATE INDEX job_created ON job(created_at);
CREATE INDEX job_set ON job(set_hash);

CREATE TABLE job_input (
    job_id   INTEGER NOT NULL REFERENCES job(id),
    rel_path TEXT NOT NULL,                    -- relative to the job's root
    role     TEXT NOT NULL CHECK (role IN ('mesh','mtl','texture')),
    size     INTEGER NOT NULL,
    mtime_ns INTEGER NOT NULL,
    ino      INTEGER NOT NULL,
    sha256   TEXT NOT NULL,
    PRIMARY KEY (job_id, rel_path)
) STRICT;
CREATE INDEX job_input_hash ON job_input(sha256);

CREATE TABLE job_output (
    job_id INTEGER NOT NULL REFERENCES job(id),
    path   TEXT NOT NULL,                      -- absolute
    bytes  INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    PRIMARY KEY (job_id, path)
) STRICT;
CREATE INDEX job_output_hash ON job_output(sha256);

-- Every place a job's input set was seen (the same content copied or renamed elsewhere).
CREATE TABLE sighting (
    job_id   INTEGER NOT NULL REFERENCES job(id),
    root     TEXT NOT NULL,
    rel_path TEXT NOT NULL,
    seen_at  INTEGER NOT NULL,
    PRIMARY KEY (job_id, root, rel_path)
) STRICT;

CREATE TABLE attempt (
    id          INTEGER PRIMARY KEY,
    job_id      INTEGER NOT NULL REFERENCES job(id),
    n           INTEGER NOT NULL,
    owner       TEXT NOT NULL,
    host        TEXT NOT NULL,
    app_version TEXT NOT NULL,
    started_at  INTEGER NOT NULL,
    finished_at INTEGER,
    outcome     TEXT CHECK (outcome IN ('ok','retry','failed','quarantined','interrupted')),
    error_kind  TEXT,
    error       TEXT,
    wall_ms     REAL
) STRICT;
CREATE INDEX attempt_job ON attempt(job_id, n);
CREATE INDEX attempt_started ON attempt(started_at);

CREATE TABLE step_timing (
    attempt_id      INTEGER NOT NULL REFERENCES attempt(id),
    idx             INTEGER NOT NULL,
    kind            TEXT NOT NULL,
    wall_ms         REAL NOT NULL,
    vertices_before INTEGER NOT NULL,
    vertices_after  INTEGER NOT NULL,
    faces_before    INTEGER NOT NULL,
    faces_after     INTEGER NOT NULL,
    figures_json    TEXT NOT NULL,
    PRIMARY KEY (attempt_id, idx)
) STRICT;

-- Scans that are not (yet) jobs and have waited too long: a member missing or unreadable.
CREATE TABLE waiting (
    root       TEXT NOT NULL,
    rel_path   TEXT NOT NULL,
    reason     TEXT NOT NULL,
    first_seen INTEGER NOT NULL,
    updated_at INTEGER NOT NULL,
    PRIMARY KEY (root, rel_path)
) STRICT;
"#;

/// The preview picture of a finished job (absolute path; NULL when none was drawn).
const V2: &str = r#"
ALTER TABLE job ADD COLUMN preview TEXT;
"#;

/// The web dashboard (docs/service.md "Web dashboard and metrics"): its job list, newest
/// first with keyset pagination on `id`, filtered by state, by watched folder or by a part
/// of the name (a covering scan of `(id, rel_path)` instead of the wide rows), and its
/// counts and processing-time histogram by state and folder (covering, too).
const V3: &str = r#"
CREATE INDEX job_state_id ON job(state, id);
CREATE INDEX job_root_id ON job(root, id);
CREATE INDEX job_id_name ON job(id, rel_path);
CREATE INDEX job_state_root_time ON job(state, root, process_ms);
"#;

/// A `.gltf` scan's external buffers (`.bin`) become set members with the role `buffer`.
/// SQLite cannot alter a CHECK constraint, so the table is rebuilt with the wider one.
const V4: &str = r#"
CREATE TABLE job_input_v4 (
    job_id   INTEGER NOT NULL REFERENCES job(id),
    rel_path TEXT NOT NULL,
    role     TEXT NOT NULL CHECK (role IN ('mesh','mtl','texture','buffer')),
    size     INTEGER NOT NULL,
    mtime_ns INTEGER NOT NULL,
    ino      INTEGER NOT NULL,
    sha256   TEXT NOT NULL,
    PRIMARY KEY (job_id, rel_path)
) STRICT;
INSERT INTO job_input_v4(rowid, job_id, rel_path, role, size, mtime_ns, ino, sha256)
    SELECT rowid, job_id, rel_path, role, size, mtime_ns, ino, sha256 FROM job_input;
DROP TABLE job_input;
ALTER TABLE job_input_v4 RENAME TO job_input;
CREATE INDEX job_input_hash ON job_input(sha256);
"#;
