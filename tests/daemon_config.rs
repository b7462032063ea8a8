//! Configuration checks and the systemd unit: `validate-config` exit codes, the shipped
//! config, `systemd-analyze verify` when the tool exists.

mod common;
mod daemon_support;

use daemon_support::*;
use std::process::Command;

#[test]
fn validate_config_accepts_a_good_config_and_exits_78_on_a_bad_one() {
    let lab = Lab::new(1.0, "");
    let (code, out, err) = lab.cli(&["validate-config"]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("ok"), "{out}");

    // Output inside the watched folder, unknown recipe step, nonsense quiet period.
    let bad = lab.dir.path().join("bad.toml");
    std::fs::write(
        lab.dir.path().join("bad-recipe.toml"),
        "[[step]]\nkind = \"sharpen\"\n",
    )
    .unwrap();
    std::fs::write(
        &bad,
        format!(
            "state_dir = {:?}\n[[watch]]\npath = {:?}\noutput = {:?}\nrecipe = {:?}\nquiet_period_secs = -1\n",
            lab.dir.path().join("state"),
            lab.inbox(),
            lab.inbox().join("out"),
            lab.dir.path().join("bad-recipe.toml")
        ),
    )
    .unwrap();
    let run = |args: &[&str]| {
        Command::new(BIN)
            .args(args)
            .arg("--config")
            .arg(&bad)
            .output()
            .unwrap()
    };
    let out = run(&["validate-config"]);
    assert_eq!(out.status.code(), Some(78));
    let err = String::from_utf8_lossy(&out.stderr);
    for needle in [
        "must not contain one another",
        "sharpen",
        "quiet_period_secs",
    ] {
        assert!(err.contains(needle), "{needle}: {err}");
    }
    // The daemon refuses the same config with the same code (RestartPreventExitStatus=78).
    assert_eq!(run(&["daemon"]).status.code(), Some(78));
    // Unknown keys and syntax errors too.
    std::fs::write(&bad, "wrokers = 1\n").unwrap();
    assert_eq!(run(&["validate-config"]).status.code(), Some(78));
}

#[test]
fn shipped_config_is_valid() {
    // config/scanmill.toml creates ./inbox etc. on start, so validation needs no folders.
    let out = Command::new(BIN)
        .args(["validate-config", "--config", "config/scanmill.toml"])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `systemd-analyze`, which .ci/run installs: a machine without it fails these tests
/// rather than skipping the check quietly.
fn systemd_analyze() -> Command {
    let probe = Command::new("systemd-analyze").arg("--version").output();
    assert!(
        probe.is_ok_and(|p| p.status.success()),
        "systemd-analyze is needed to check the unit (Debian package systemd)"
    );
    Command::new("systemd-analyze")
}

/// The shipped unit with the binary under test in place of the installed one.
fn unit_under_test(dir: &std::path::Path) -> std::path::PathBuf {
    let unit = std::fs::read_to_string("systemd/scanmill.service").unwrap();
    let path = dir.join("scanmill.service");
    let bin = std::fs::canonicalize(BIN).unwrap();
    std::fs::write(
        &path,
        unit.replace("/usr/local/bin/scanmill", bin.to_str().unwrap()),
    )
    .unwrap();
    path
}

#[test]
fn systemd_unit_rates_safe_and_keeps_the_service_up() {
    let dir = tempfile::tempdir().unwrap();
    let path = unit_under_test(dir.path());
    let out = systemd_analyze()
        .args(["security", "--offline=true"])
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let level: f64 = text
        .lines()
        .find_map(|l| {
            l.split("Overall exposure level for scanmill.service: ")
                .nth(1)
        })
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no exposure level in: {text}"));
    assert!(level <= 1.0, "exposure {level} > 1.0:\n{text}");
    let unit = std::fs::read_to_string(&path).unwrap();
    for key in [
        "MemoryMax=",
        "TasksMax=",
        "OOMPolicy=continue",
        "Restart=always",
        "StartLimitIntervalSec=0",
        "ProtectHome=yes",
        "TemporaryFileSystem=",
        "InaccessiblePaths=",
        "KillMode=mixed",
    ] {
        assert!(unit.contains(key), "{key} missing from the unit");
    }
}

#[test]
fn systemd_unit_verifies() {
    let unit = std::fs::read_to_string("systemd/scanmill.service").unwrap();
    for key in [
        "Type=notify",
        "RestartPreventExitStatus=78",
        "ProtectSystem=strict",
        "NoNewPrivileges=yes",
        "PrivateTmp=yes",
        "UMask=0027",
        "WatchdogSec=",
    ] {
        assert!(unit.contains(key), "{key} missing from the unit");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = unit_under_test(dir.path());
    let out = systemd_analyze().arg("verify").arg(&path).output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "systemd-analyze verify: {text}");
    assert!(
        !text.contains("scanmill.service:"),
        "warnings about the unit: {text}"
    );
}

#[test]
fn absurd_numbers_are_refused_at_validation_not_at_run_time() {
    for (key, value) in [
        ("job_timeout_secs", "1e300"),
        ("rescan_secs", "1e19"),
        ("retry_max_secs", "inf"),
        ("drain_timeout_secs", "nan"),
        ("max_attempts", "1000"),
        ("job_memory_mb", "1"),
    ] {
        let lab = Lab::new(1.0, "");
        // Set the key in place (the lab's config may already have it).
        let config: String = std::fs::read_to_string(&lab.config)
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with(&format!("{key} =")))
            .map(|l| format!("{l}\n"))
            .collect();
        std::fs::write(&lab.config, format!("{key} = {value}\n{config}")).unwrap();
        let (code, out, err) = lab.cli(&["validate-config"]);
        assert_eq!(code, 78, "{key} = {value}: {out}{err}");
        assert!(err.contains(&format!("{key} must")), "{key}: {err}");
        let out = Command::new(BIN)
            .args(["daemon", "--config"])
            .arg(&lab.config)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(78), "{key} = {value}");
    }
}

#[test]
fn an_output_folder_linked_into_the_watched_folder_is_refused() {
    let lab = Lab::new(1.0, "");
    let inside = lab.inbox().join("results");
    std::fs::create_dir(&inside).unwrap();
    let link = lab.dir.path().join("out-link");
    std::os::unix::fs::symlink(&inside, &link).unwrap();
    let config = std::fs::read_to_string(&lab.config).unwrap();
    let outbox = format!("{:?}", lab.outbox());
    assert!(config.contains(&outbox));
    std::fs::write(&lab.config, config.replace(&outbox, &format!("{link:?}"))).unwrap();
    let (code, out, err) = lab.cli(&["validate-config"]);
    assert_eq!(code, 78, "{out}{err}");
    assert!(err.contains("must not contain one another"), "{err}");
}
