//! Why an attempt failed: the kinds documented to users in docs/service.md ("Why a job
//! failed"), stored in the `error_kind` columns under their snake_case names.

use serde::{Deserialize, Serialize};

/// The kind of a failed attempt. The serialised name (snake_case) is what the worker
/// protocol carries, the store records and `history`/`show` print.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureKind {
    /// The scan is not a valid mesh, or breaks an input limit.
    Input,
    /// A recipe step failed on this scan.
    Step,
    /// The result could not be written (transient).
    Output,
    /// The input set is larger than `max_input_bytes`.
    TooLarge,
    /// The recipe file is unreadable.
    Recipe,
    /// The recipe changed after the job was queued.
    RecipeChanged,
    /// A member was removed while the job ran.
    InputVanished,
    /// A member changed while the job ran.
    InputChanged,
    /// An internal error in scanmill.
    Panic,
    /// The worker ran past `job_timeout_secs`, or the supervising thread did not finish.
    Timeout,
    /// The worker's allocation failed under `job_memory_mb`.
    OutOfMemory,
    /// The worker reached `job_cpu_secs`.
    CpuLimit,
    /// The worker was killed by someone else (the kernel's OOM killer, an operator).
    WorkerKilled,
    /// The worker died of a signal or exited without a result.
    WorkerCrashed,
    /// The worker said something the daemon does not understand.
    WorkerProtocol,
    /// The worker could not be started.
    Spawn,
    /// The daemon died while the job ran.
    DaemonStopped,
    /// The attempt was stopped (a shutdown) and not counted: the attempt log only.
    Interrupted,
    /// Shared queue: the attempt's lease expired (its daemon died, hung or lost the
    /// database); counted, like a daemon that stopped.
    LeaseExpired,
    /// Shared queue: the attempt came back after its job was taken over; fenced out,
    /// nothing of it published. The attempt log only.
    Superseded,
}

impl FailureKind {
    /// Every kind, in the order of docs/service.md.
    pub const ALL: [FailureKind; 20] = [
        FailureKind::Input,
        FailureKind::Step,
        FailureKind::Output,
        FailureKind::TooLarge,
        FailureKind::Recipe,
        FailureKind::RecipeChanged,
        FailureKind::InputVanished,
        FailureKind::InputChanged,
        FailureKind::Panic,
        FailureKind::Timeout,
        FailureKind::OutOfMemory,
        FailureKind::CpuLimit,
        FailureKind::WorkerKilled,
        FailureKind::WorkerCrashed,
        FailureKind::WorkerProtocol,
        FailureKind::Spawn,
        FailureKind::DaemonStopped,
        FailureKind::Interrupted,
        FailureKind::LeaseExpired,
        FailureKind::Superseded,
    ];

    /// The documented name (as serialised).
    pub fn as_str(self) -> &'static str {
        match self {
            FailureKind::Input => "input",
            FailureKind::Step => "step",
            FailureKind::Output => "output",
            FailureKind::TooLarge => "too_large",
            FailureKind::Recipe => "recipe",
            FailureKind::RecipeChanged => "recipe_changed",
            FailureKind::InputVanished => "input_vanished",
            FailureKind::InputChanged => "input_changed",
            FailureKind::Panic => "panic",
            FailureKind::Timeout => "timeout",
            FailureKind::OutOfMemory => "out_of_memory",
            FailureKind::CpuLimit => "cpu_limit",
            FailureKind::WorkerKilled => "worker_killed",
            FailureKind::WorkerCrashed => "worker_crashed",
            FailureKind::WorkerProtocol => "worker_protocol",
            FailureKind::Spawn => "spawn",
            FailureKind::DaemonStopped => "daemon_stopped",
            FailureKind::Interrupted => "interrupted",
            FailureKind::LeaseExpired => "lease_expired",
            FailureKind::Superseded => "superseded",
        }
    }

    /// The kind of a documented name, as the store holds it.
    pub fn from_name(name: &str) -> Option<FailureKind> {
        FailureKind::ALL.into_iter().find(|k| k.as_str() == name)
    }

    /// A member of the input set went away or changed: not the scan's fault, and a new
    /// version of it is a new job.
    pub fn is_input_gone(self) -> bool {
        matches!(self, FailureKind::InputVanished | FailureKind::InputChanged)
    }
}

impl std::fmt::Display for FailureKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl rusqlite::ToSql for FailureKind {
    fn to_sql(&self) -> rusqlite::Result<rusqlite::types::ToSqlOutput<'_>> {
        Ok(self.as_str().into())
    }
}

#[cfg(test)]
mod tests {
    use super::FailureKind;

    #[test]
    fn names_are_the_serialised_ones_and_the_documented_ones() {
        let doc = include_str!("../../docs/service.md");
        for kind in FailureKind::ALL {
            let json = serde_json::to_string(&kind).unwrap();
            assert_eq!(json, format!("\"{}\"", kind.as_str()));
            assert_eq!(serde_json::from_str::<FailureKind>(&json).unwrap(), kind);
            assert!(
                doc.contains(&format!("`{kind}`")),
                "{kind} not in docs/service.md"
            );
        }
    }
}
