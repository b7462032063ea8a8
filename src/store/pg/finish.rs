//! How an attempt ends on PostgreSQL, fenced: the job row is locked only where the
//! attempt's token still matches, and the end (or the publication, [`Fence`]) happens while
//! that lock is held, in one transaction.

use super::{ConnInfo, DbError, is_retryable};
use crate::store::attempt::{
    AttemptEnd, AttemptRecord, AttemptWriter, FailurePlan, record_done, record_end,
};
use crate::store::{
    ClaimedJob, FailureKind, FinalState, Finish, JobDone, RetryPolicy, StoreError, now_ms,
};
use postgres::{Client, NoTls, Transaction};
use std::sync::Mutex;
use std::time::{Duration, Instant};

type DbResult<T> = std::result::Result<T, DbError>;

/// Whether `job`'s attempt still holds it; locks the row until the transaction ends.
fn lock_if_held(tx: &mut Transaction<'_>, job: &ClaimedJob) -> DbResult<bool> {
    Ok(tx
        .query_opt(
            "SELECT 1 FROM job WHERE id=$1 AND attempt_token=$2 FOR UPDATE",
            &[&job.id, &job.attempt_id],
        )?
        .is_some())
}

/// Records the attempt as superseded (another attempt has the job; nothing of this one
/// was published). Leaves an attempt already closed otherwise as it is.
fn record_superseded(tx: &mut Transaction<'_>, job: &ClaimedJob, wall_ms: f64) -> DbResult<()> {
    tx.execute(
        "UPDATE attempt SET finished_at=coalesce(finished_at, $2), outcome='superseded',
            error_kind=$3, wall_ms=$4,
            error='it lost its lease and came back after the job was taken over; nothing of it was published'
         WHERE id=$1 AND (outcome IS NULL OR outcome='lost')",
        &[
            &job.attempt_id,
            &now_ms(),
            &FailureKind::Superseded.as_str(),
            &wall_ms,
        ],
    )?;
    Ok(())
}

/// The outcome recorded for this attempt already, if any (a retried finish).
fn recorded_outcome(tx: &mut Transaction<'_>, job: &ClaimedJob) -> DbResult<Option<String>> {
    Ok(tx
        .query_one(
            "SELECT outcome FROM attempt WHERE id=$1",
            &[&job.attempt_id],
        )?
        .get(0))
}

pub(super) fn finish_in(
    tx: &mut Transaction<'_>,
    job: &ClaimedJob,
    outcome: &Finish,
    retry: RetryPolicy,
    wall_ms: f64,
) -> DbResult<FinalState> {
    if !lock_if_held(tx, job)? {
        record_superseded(tx, job, wall_ms)?;
        return Ok(FinalState::Superseded);
    }
    if let Some(recorded) = recorded_outcome(tx, job)? {
        // Recorded already (by the fence, or before a lost reply): nothing twice.
        return Ok(match recorded.as_str() {
            "ok" => FinalState::Done,
            "retry" => FinalState::RetryLater,
            "quarantined" => FinalState::Quarantined,
            "interrupted" => FinalState::Requeued,
            _ => FinalState::Failed,
        });
    }
    let end = AttemptEnd {
        job,
        now: now_ms(),
        wall_ms,
    };
    record_end(tx, &end, outcome, retry)
}

/// The rows that end an attempt, in PostgreSQL's dialect: as the SQLite store's, and each
/// also drops the job's lease and fencing token.
impl AttemptWriter for Transaction<'_> {
    type Error = DbError;

    fn job_done(&mut self, end: &AttemptEnd<'_>, done: &JobDone) -> DbResult<()> {
        self.execute(
            "UPDATE job SET state='done', retryable=0, finished_at=$2, updated_at=$2, lease_owner=NULL,
                lease_until=NULL, output_dir=$3, error_kind=NULL, error=NULL, in_vertices=$4,
                in_faces=$5, out_vertices=$6, out_faces=$7, process_ms=$8, report_json=$9, preview=$10
             WHERE id=$1",
            &[
                &end.job.id,
                &end.now,
                &done.output_dir,
                &done.counts.in_vertices,
                &done.counts.in_faces,
                &done.counts.out_vertices,
                &done.counts.out_faces,
                &done.process_ms,
                &done.report_json,
                &done.preview,
            ],
        )?;
        self.execute("DELETE FROM job_output WHERE job_id=$1", &[&end.job.id])?;
        for f in &done.outputs {
            self.execute(
                "INSERT INTO job_output(job_id, path, bytes, sha256) VALUES ($1, $2, $3, $4)
                 ON CONFLICT (job_id, path) DO UPDATE SET bytes=excluded.bytes, sha256=excluded.sha256",
                &[&end.job.id, &f.path, &(f.bytes as i64), &f.sha256],
            )?;
        }
        for (i, s) in done.steps.iter().enumerate() {
            self.execute(
                "INSERT INTO step_timing(attempt_id, idx, kind, wall_ms, vertices_before, vertices_after,
                    faces_before, faces_after, figures_json) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9)",
                &[
                    &end.job.attempt_id,
                    &(i as i64 + 1),
                    &s.kind,
                    &s.wall_ms,
                    &s.vertices_before,
                    &s.vertices_after,
                    &s.faces_before,
                    &s.faces_after,
                    &s.figures_json,
                ],
            )?;
        }
        Ok(())
    }

    fn job_failed(
        &mut self,
        end: &AttemptEnd<'_>,
        kind: FailureKind,
        plan: &FailurePlan<'_>,
    ) -> DbResult<()> {
        self.execute(
            "UPDATE job SET state=$2, retryable=$3, run_after=$4, finished_at=$5, updated_at=$5,
                lease_owner=NULL, lease_until=NULL, error_kind=$6, error=$7 WHERE id=$1",
            &[
                &end.job.id,
                &plan.state,
                &plan.retryable,
                &plan.run_after,
                &end.now,
                &kind.as_str(),
                &plan.message.as_ref(),
            ],
        )?;
        Ok(())
    }

    fn job_requeued(&mut self, end: &AttemptEnd<'_>) -> DbResult<()> {
        self.execute(
            "UPDATE job SET state='queued', attempts=greatest(attempts-1, 0), run_after=$2,
                updated_at=$2, lease_owner=NULL, lease_until=NULL, attempt_token=NULL WHERE id=$1",
            &[&end.job.id, &end.now],
        )?;
        Ok(())
    }

    fn close_attempt(&mut self, a: &AttemptRecord<'_>) -> DbResult<()> {
        self.execute(
            "UPDATE attempt SET finished_at=$2, outcome=$3, error_kind=$4, error=$5, wall_ms=$6 WHERE id=$1",
            &[
                &a.attempt_id,
                &a.finished_at,
                &a.outcome,
                &a.kind.map(FailureKind::as_str),
                &a.message,
                &a.wall_ms,
            ],
        )?;
        Ok(())
    }
}

/// What [`Fence::hold`] did.
pub enum Fenced<T> {
    /// The attempt held its job: `publish` ran while the row was locked.
    Held(T),
    /// Another attempt has the job: `publish` did not run; recorded `superseded`.
    Superseded,
}

/// Publishing under the fencing token, from a job's own thread (its own connection,
/// shared by the daemon's job threads and connected again when lost).
pub struct Fence {
    info: ConnInfo,
    client: Mutex<Option<Client>>,
}

impl Drop for Fence {
    /// Closing the client blocks (the service drops its fence inside its runtime).
    fn drop(&mut self) {
        let client = self.client.get_mut().map(Option::take).unwrap_or(None);
        super::off_runtime(move || drop(client));
    }
}

/// Tries to lock the job row before giving up on publishing (a server restart takes a
/// few seconds; past this the attempt fails transiently and is retried).
const FENCE_TRIES: u32 = 8;

impl Fence {
    pub fn new(info: ConnInfo) -> Fence {
        Fence {
            info,
            client: Mutex::new(None),
        }
    }

    /// Locks `job`'s row where its token matches, runs `publish` (the no-replace rename)
    /// while the lock holds, records a `Finish::Done` it returns in the same transaction,
    /// and commits. `publish` runs at most once. If the commit fails after `publish` ran,
    /// its result is returned all the same: the service records it (if the token still
    /// matches), else the rerun finds this very output and publishes nothing twice.
    pub fn hold<E>(
        &self,
        job: &ClaimedJob,
        started: Instant,
        publish: impl FnOnce() -> std::result::Result<Finish, E>,
    ) -> std::result::Result<Fenced<std::result::Result<Finish, E>>, StoreError> {
        let mut guard = self.client.lock().unwrap_or_else(|p| p.into_inner());
        let mut pause = Duration::from_millis(250);
        let mut tries = 0;
        let mut publish = Some(publish);
        loop {
            tries += 1;
            match self.try_hold(&mut guard, job, started, &mut publish) {
                Ok(done) => return Ok(done),
                Err(e) => {
                    let retryable = matches!(&e, DbError::Pg(pg) if is_retryable(pg));
                    *guard = None;
                    if !retryable || tries >= FENCE_TRIES {
                        return Err(self.error(e));
                    }
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_secs(5));
                }
            }
        }
    }

    fn try_hold<E>(
        &self,
        guard: &mut Option<Client>,
        job: &ClaimedJob,
        started: Instant,
        publish: &mut Option<impl FnOnce() -> std::result::Result<Finish, E>>,
    ) -> DbResult<Fenced<std::result::Result<Finish, E>>> {
        if guard.as_ref().is_none_or(|c| c.is_closed()) {
            *guard = Some(self.info.config.connect(NoTls)?);
        }
        let client = guard.as_mut().expect("connected");
        let mut tx = client.transaction()?;
        let wall_ms = || started.elapsed().as_secs_f64() * 1e3;
        if !lock_if_held(&mut tx, job)? {
            record_superseded(&mut tx, job, wall_ms())?;
            tx.commit()?;
            return Ok(Fenced::Superseded);
        }
        let publish = publish.take().expect("runs once");
        let result = publish();
        let recorded = match &result {
            Ok(Finish::Done(done)) => {
                let end = AttemptEnd {
                    job,
                    now: now_ms(),
                    wall_ms: wall_ms(),
                };
                record_done(&mut tx, &end, done).and_then(|_| Ok(tx.commit()?))
            }
            _ => Ok(tx.commit()?),
        };
        if let Err(e) = recorded {
            let message = match e {
                DbError::Pg(pg) => pg.to_string(),
                DbError::Data(d) => d,
            };
            tracing::warn!(
                "published, but not recorded with the lease held ({message}); the service records it"
            );
            *guard = None;
        }
        Ok(Fenced::Held(result))
    }

    fn error(&self, e: DbError) -> StoreError {
        match e {
            DbError::Pg(source) => StoreError::Postgres {
                target: self.info.shown.clone(),
                source,
            },
            DbError::Data(message) => StoreError::Data {
                target: self.info.shown.clone(),
                message,
            },
        }
    }
}
