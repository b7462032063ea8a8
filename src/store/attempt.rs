//! How an attempt ends, the same in both stores: which rows each outcome writes, where a
//! failure leaves its job, and what the attempt's row records. Each store writes these
//! rows in its own SQL dialect ([`AttemptWriter`]).

use super::{
    ClaimedJob, FailureKind, FinalState, Finish, JobDone, MAX_ERROR_BYTES, RetryPolicy, cut,
};
use std::borrow::Cow;

/// The attempt that ends: its job, when (Unix ms) and after how long.
pub(crate) struct AttemptEnd<'j> {
    pub job: &'j ClaimedJob,
    pub now: i64,
    pub wall_ms: f64,
}

/// What the attempt's row records when the attempt ends.
pub(crate) struct AttemptRecord<'a> {
    pub attempt_id: i64,
    pub finished_at: i64,
    pub outcome: &'a str,
    pub kind: Option<FailureKind>,
    pub message: Option<&'a str>,
    pub wall_ms: f64,
}

impl AttemptEnd<'_> {
    fn record<'a>(
        &self,
        outcome: &'a str,
        failure: Option<(FailureKind, &'a str)>,
    ) -> AttemptRecord<'a> {
        AttemptRecord {
            attempt_id: self.job.attempt_id,
            finished_at: self.now,
            outcome,
            kind: failure.map(|(kind, _)| kind),
            message: failure.map(|(_, message)| message),
            wall_ms: self.wall_ms,
        }
    }
}

/// Where a failed attempt leaves its job: failed for good unless transient; quarantined
/// when transient with no attempts left; otherwise retried after the back-off.
pub(crate) struct FailurePlan<'m> {
    /// The job's new state, and whether it will be retried (0 or 1, as the row stores it).
    pub state: &'static str,
    pub retryable: i64,
    /// When a retried job may run again (Unix ms).
    pub run_after: i64,
    /// The attempt's outcome.
    pub outcome: &'static str,
    pub final_state: FinalState,
    /// The message, cut to [`MAX_ERROR_BYTES`] so that it cannot fill the database.
    pub message: Cow<'m, str>,
}

impl<'m> FailurePlan<'m> {
    fn new(end: &AttemptEnd<'_>, message: &'m str, transient: bool, retry: RetryPolicy) -> Self {
        let job = end.job;
        let (state, retryable, outcome, final_state) = if !transient {
            ("failed", 0, "failed", FinalState::Failed)
        } else if job.attempt >= job.max_attempts {
            ("quarantined", 0, "quarantined", FinalState::Quarantined)
        } else {
            ("failed", 1, "retry", FinalState::RetryLater)
        };
        FailurePlan {
            state,
            retryable,
            run_after: end.now + backoff_ms(job.attempt, retry.base_secs, retry.max_secs),
            outcome,
            final_state,
            message: cut(message, MAX_ERROR_BYTES),
        }
    }
}

/// Exponential backoff after `attempts` counted failures: base·2^(attempts-1), capped.
pub fn backoff_ms(attempts: u32, base_secs: f64, max_secs: f64) -> i64 {
    let exp = attempts.saturating_sub(1).min(30) as i32;
    let secs = (base_secs * 2f64.powi(exp)).min(max_secs);
    (secs * 1000.0) as i64
}

/// The rows an attempt's end writes, in one store's dialect (implemented by each store's
/// transaction); [`record_end`] chooses which.
pub(crate) trait AttemptWriter {
    type Error;

    /// The job row of a job done, its published files and the attempt's step timings.
    fn job_done(&mut self, end: &AttemptEnd<'_>, done: &JobDone) -> Result<(), Self::Error>;

    /// The job row of a failed attempt, as `plan` disposes of it.
    fn job_failed(
        &mut self,
        end: &AttemptEnd<'_>,
        kind: FailureKind,
        plan: &FailurePlan<'_>,
    ) -> Result<(), Self::Error>;

    /// The job row of an interrupted attempt: queued again, the attempt not counted.
    fn job_requeued(&mut self, end: &AttemptEnd<'_>) -> Result<(), Self::Error>;

    /// The attempt's row.
    fn close_attempt(&mut self, record: &AttemptRecord<'_>) -> Result<(), Self::Error>;
}

/// Records how an attempt ended and moves its job on.
pub(crate) fn record_end<W: AttemptWriter>(
    w: &mut W,
    end: &AttemptEnd<'_>,
    outcome: &Finish,
    retry: RetryPolicy,
) -> Result<FinalState, W::Error> {
    match outcome {
        Finish::Done(done) => record_done(w, end, done),
        Finish::Failed {
            kind,
            message,
            transient,
        } => {
            let plan = FailurePlan::new(end, message, *transient, retry);
            w.job_failed(end, *kind, &plan)?;
            w.close_attempt(&end.record(plan.outcome, Some((*kind, &plan.message))))?;
            Ok(plan.final_state)
        }
        Finish::Interrupted { reason } => {
            w.job_requeued(end)?;
            w.close_attempt(&end.record("interrupted", Some((FailureKind::Interrupted, reason))))?;
            Ok(FinalState::Requeued)
        }
    }
}

/// Records a job done (also what the shared queue's fence records while it holds the row).
pub(crate) fn record_done<W: AttemptWriter>(
    w: &mut W,
    end: &AttemptEnd<'_>,
    done: &JobDone,
) -> Result<FinalState, W::Error> {
    w.job_done(end, done)?;
    w.close_attempt(&end.record("ok", None))?;
    Ok(FinalState::Done)
}
