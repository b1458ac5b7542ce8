//! Time to the first picture in the viewer, headless (Slint's testing backend with
//! the software renderer, real time): opens FILE as `viewer FILE` would, pumps the
//! controller until the first frame is on screen, then until the refined frame of
//! the resting view is; prints both times, their pyramid levels and the bytes the
//! process read from disk.
//!
//! ```sh
//! cargo run --release -p viewer --example first_picture -- big.vol
//! ```

use std::time::{Duration, Instant};

use i_slint_backend_testing::{TestingBackend, TestingBackendOptions};
use slint::ComponentHandle;
use viewer::{Source, Viewer};

fn main() {
    let Some(path) = std::env::args_os().nth(1) else {
        eprintln!("usage: first_picture FILE");
        std::process::exit(2);
    };
    slint::platform::set_platform(Box::new(TestingBackend::new(TestingBackendOptions {
        mock_time: false,
        threading: false,
        renderer_name: Some("software".into()),
    })))
    .expect("the first platform of this process");
    let start = Instant::now();
    let v = match Viewer::new(Source::File(path.into()), None) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::exit(1);
        }
    };
    let opened = start.elapsed();
    v.ui()
        .window()
        .set_size(slint::LogicalSize::new(1000.0, 700.0));
    v.ui().show().expect("a headless window");
    v.pump();
    v.ui().invoke_reset_view();
    println!("opened in {:.0} ms", opened.as_secs_f64() * 1e3);
    let mut first = None;
    loop {
        slint::platform::update_timers_and_animations();
        v.pump();
        if let Some((stats, moving)) = v.last_stats() {
            if first.is_none() {
                first = Some(start.elapsed());
                println!(
                    "first picture after {:.0} ms: level {}, {}×{}, {:.1} MB read from disk",
                    start.elapsed().as_secs_f64() * 1e3,
                    stats.level,
                    stats.width,
                    stats.height,
                    raycaster::io::process_bytes_read() as f64 / 1e6
                );
            }
            if !moving && v.idle() {
                println!(
                    "refined picture after {:.0} ms: level {}, {:.1} MB read from disk",
                    start.elapsed().as_secs_f64() * 1e3,
                    stats.level,
                    raycaster::io::process_bytes_read() as f64 / 1e6
                );
                break;
            }
        }
        if start.elapsed() > Duration::from_secs(600) {
            eprintln!("no refined frame after 10 minutes");
            std::process::exit(1);
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}
