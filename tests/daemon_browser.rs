//! The dashboard in a real browser: headless Chromium (Debian package `chromium`, which
//! .ci/run installs; this test fails when it is missing) loads the job list and the job
//! page of a processed scan from the running daemon, the preview pictures are decoded
//! (natural width > 0), and screenshots of both pages are taken (target/web-screenshots).
//!
//! The pages forbid script (Content-Security-Policy), so the decoding check runs on a copy
//! of each page's markup as served, with a `<base>` pointing at the daemon and a few lines
//! of script added, loaded from a file: the images still come from the daemon over HTTP.

mod common;
mod daemon_support;

use daemon_support::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn chromium() -> PathBuf {
    let name = std::env::var_os("SCANMILL_CHROMIUM").unwrap_or_else(|| "chromium".into());
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(&name))
            .find(|p| p.is_file())
    });
    found.unwrap_or_else(|| {
        panic!(
            "headless Chromium is needed: apt-get install chromium (.ci/run does), or set SCANMILL_CHROMIUM"
        )
    })
}

/// Runs headless Chromium with `args` on `url`; returns its stdout. Killed after 120 s.
fn run_chromium(profile: &Path, args: &[&str], url: &str) -> String {
    let mut child = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--no-first-run",
            "--virtual-time-budget=10000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromium");
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut s).unwrap();
        s
    });
    let code = wait_exit(&mut child, 120);
    if code.is_none() {
        let _ = child.kill();
        let _ = child.wait();
        panic!("chromium did not finish within 120 s on {url}");
    }
    reader.join().unwrap()
}

fn base_url(lab: &Lab) -> String {
    let logs = lab.logs();
    let at = logs
        .find("web dashboard on http://")
        .expect("address logged");
    logs[at + "web dashboard on ".len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .to_string()
}

fn fetch(url: &str) -> String {
    ureq::get(url)
        .call()
        .unwrap()
        .body_mut()
        .read_to_string()
        .unwrap()
}

const PROBE: &str = "<script>window.addEventListener('load', () => {\
    document.body.setAttribute('data-widths', [...document.images].map(i => i.naturalWidth).join(','));\
    });</script>";

/// The natural widths of every image of the page at `url`, as Chromium decoded them.
fn image_widths(work: &Path, base: &str, url: &str, name: &str) -> Vec<u32> {
    let html = fetch(url)
        .replacen("<head>", &format!("<head><base href=\"{base}\">"), 1)
        .replacen("</body>", &format!("{PROBE}</body>"), 1);
    let file = work.join(format!("{name}.html"));
    std::fs::write(&file, html).unwrap();
    let dom = run_chromium(
        &work.join("profile"),
        &["--dump-dom"],
        &format!("file://{}", file.display()),
    );
    let at = dom
        .find("data-widths=\"")
        .unwrap_or_else(|| panic!("probe did not run:\n{dom}"));
    let rest = &dom[at + 13..];
    rest[..rest.find('"').unwrap()]
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|w| w.parse().unwrap())
        .collect()
}

/// A screenshot of the live page; checks it decodes and is not blank.
fn screenshot(work: &Path, url: &str, out: &Path, size: &str) {
    run_chromium(
        &work.join("profile"),
        &[
            &format!("--screenshot={}", out.display()),
            &format!("--window-size={size}"),
        ],
        url,
    );
    let img = image::open(out)
        .unwrap_or_else(|e| panic!("{}: {e}", out.display()))
        .to_rgb8();
    let first = *img.get_pixel(0, 0);
    let differing = img.pixels().filter(|p| **p != first).count();
    assert!(
        differing > (img.width() * img.height() / 20) as usize,
        "{} looks blank",
        out.display()
    );
}

#[test]
fn job_list_and_job_page_render_in_headless_chromium_with_decoded_previews() {
    let browser = chromium();
    let lab = Lab::new(0.3, "[web]\nenabled = true\nlisten = \"127.0.0.1:0\"\n");
    let _d = KillOnDrop(lab.start(&[]));
    let base = base_url(&lab);
    copy_james(&lab.inbox().join("session1"));
    std::fs::write(lab.inbox().join("bunny.ply"), bunny()).unwrap();
    assert!(
        wait_for(120, || lab.count_state("done") == 2),
        "{}",
        lab.logs()
    );
    let james = lab
        .jobs()
        .iter()
        .find(|j| j["input"].as_str().unwrap().ends_with("james.obj"))
        .unwrap()["id"]
        .as_i64()
        .unwrap();
    let work = tempfile::tempdir().unwrap();

    // The live pages as the browser's own HTTP stack gets them.
    let dom = run_chromium(&work.path().join("profile"), &["--dump-dom"], &base);
    assert!(dom.contains("session1/james.obj"), "{browser:?}: {dom}");

    let list = image_widths(work.path(), &base, &base, "list");
    assert_eq!(list.len(), 2, "one thumbnail per job: {list:?}");
    assert!(list.iter().all(|&w| w > 0), "thumbnails decoded: {list:?}");
    let job_url = format!("{base}jobs/{james}");
    let page = image_widths(work.path(), &base, &job_url, "job");
    assert_eq!(page.len(), 1, "{page:?}");
    assert!(page[0] > 0, "preview decoded: {page:?}");

    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    screenshot(work.path(), &base, &shots.join("jobs.png"), "1280,480");
    screenshot(work.path(), &job_url, &shots.join("job.png"), "1280,1100");
}
