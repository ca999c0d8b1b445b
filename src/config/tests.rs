//! Tests of the serve flags and their validation into `Settings`.

use super::*;
use clap::Parser;

#[derive(Debug, Parser)]
struct Cli {
    #[command(flatten)]
    serve: ServeArgs,
}

fn settings_from(flags: &[&str]) -> Result<Settings, ConfigError> {
    let argv = std::iter::once("qrpose").chain(flags.iter().copied());
    Settings::try_from(Cli::try_parse_from(argv).expect("flags parse").serve)
}

#[test]
fn defaults_are_valid_and_equal_the_default_settings() {
    assert_eq!(settings_from(&[]), Ok(Settings::default()));
    assert_eq!(
        Settings::try_from(ServeArgs::default()),
        Ok(Settings::default())
    );
}

#[test]
fn the_memory_budget_follows_the_workers_and_limits_unless_given() {
    let s = settings_from(&[
        "--max-concurrent-estimations",
        "3",
        "--max-image-pixels",
        "1000000",
        "--body-limit-bytes",
        "4096",
    ])
    .expect("valid");
    assert_eq!(s.max_inflight_pixels, 3_000_000);
    assert_eq!(s.max_inflight_body_bytes, 5 * 4096);
    let s = settings_from(&[
        "--max-image-pixels",
        "1000000",
        "--max-inflight-pixels",
        "2500000",
        "--body-limit-bytes",
        "4096",
        "--max-inflight-body-bytes",
        "10000",
    ])
    .expect("valid");
    assert_eq!(
        (s.max_inflight_pixels, s.max_inflight_body_bytes),
        (2_500_000, 10_000)
    );
    let small = settings_from(&[
        "--max-image-pixels",
        "1000000",
        "--max-inflight-pixels",
        "999999",
    ]);
    assert_eq!(
        small.map_err(|e| e.flag),
        Err("max-inflight-pixels"),
        "less than one image"
    );
    let small = settings_from(&[
        "--body-limit-bytes",
        "4096",
        "--max-inflight-body-bytes",
        "4095",
    ]);
    assert_eq!(
        small.map_err(|e| e.flag),
        Err("max-inflight-body-bytes"),
        "less than one body"
    );
}

#[test]
fn flags_set_every_field() {
    let s = settings_from(&[
        "--addr",
        "0.0.0.0:9000",
        "--body-limit-bytes",
        "4096",
        "--request-timeout-ms",
        "250",
        "--worker-threads",
        "3",
        "--max-concurrent-estimations",
        "5",
        "--queue-length",
        "0",
        "--log-format",
        "json",
        "--shutdown-grace-ms",
        "0",
        "--max-image-pixels",
        "1000000",
        "--header-read-timeout-ms",
        "1500",
        "--idle-timeout-ms",
        "2500",
        "--max-connections",
        "7",
    ])
    .expect("valid flags");
    assert_eq!(s.addr, SocketAddr::from(([0, 0, 0, 0], 9000)));
    assert_eq!(s.body_limit_bytes, 4096);
    assert_eq!(s.request_timeout, Duration::from_millis(250));
    assert_eq!(s.worker_threads.get(), 3);
    assert_eq!(s.max_concurrent_estimations.get(), 5);
    assert_eq!(s.queue_length, 0);
    assert_eq!(s.log_format, LogFormat::Json);
    assert_eq!(s.shutdown_grace, Duration::ZERO);
    assert_eq!(s.max_image_pixels, 1_000_000);
    assert_eq!(s.header_read_timeout, Duration::from_millis(1500));
    assert_eq!(s.idle_timeout, Duration::from_millis(2500));
    assert_eq!(s.max_connections.get(), 7);
}

#[test]
fn rejects_values_outside_their_range_naming_the_flag() {
    let cases: [(&[&str], &str); 14] = [
        (&["--body-limit-bytes", "10"], "body-limit-bytes"),
        (&["--request-timeout-ms", "0"], "request-timeout-ms"),
        (&["--worker-threads", "0"], "worker-threads"),
        (&["--worker-threads", "100000"], "worker-threads"),
        (
            &["--max-concurrent-estimations", "0"],
            "max-concurrent-estimations",
        ),
        (&["--queue-length", "1000000"], "queue-length"),
        (&["--shutdown-grace-ms", "700000"], "shutdown-grace-ms"),
        (&["--max-image-pixels", "0"], "max-image-pixels"),
        (&["--max-image-pixels", "2000000000"], "max-image-pixels"),
        (&["--header-read-timeout-ms", "0"], "header-read-timeout-ms"),
        (
            &["--header-read-timeout-ms", "600001"],
            "header-read-timeout-ms",
        ),
        (&["--idle-timeout-ms", "0"], "idle-timeout-ms"),
        (&["--max-connections", "0"], "max-connections"),
        (&["--max-connections", "1000001"], "max-connections"),
    ];
    for (flags, flag) in cases {
        let err = settings_from(flags).expect_err(flag);
        assert_eq!(err.flag, flag, "{flags:?}");
        assert!(err.to_string().starts_with(&format!("--{flag} ")), "{err}");
    }
}

#[test]
fn an_unparseable_address_is_refused_by_the_parser() {
    let argv = ["qrpose", "--addr", "localhost"];
    assert!(Cli::try_parse_from(argv).is_err());
}
