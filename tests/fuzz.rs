//! A short seeded run of the fuzz engine ([`engine`], shared with `examples/fuzz.rs`,
//! the long run): a few thousand structure-aware mutations of scene, OBJ and profile
//! text through the parser and a tiny render, each case held to 20 s and 256 MiB.
//!
//! The long run: `cargo run --release --example fuzz -- --cases 1000000`.

#[path = "fuzz/engine.rs"]
mod engine;

use std::time::Duration;

/// Cases of the short run (about three seconds in the test profile).
const CASES: u64 = 2000;

#[test]
fn a_short_seeded_run_finds_nothing() {
    engine::MEMORY_LIMIT.store(2 << 30, std::sync::atomic::Ordering::Relaxed);
    engine::watch(Duration::from_secs(20));
    let dir = std::env::temp_dir().join(format!("octaray-fuzz-{}", std::process::id()));
    let stats = engine::run_cases(
        0x00C7_A4A7,
        0..CASES,
        &dir,
        engine::Budget::default(),
        256 << 20,
        |_| {},
    );
    let _ = std::fs::remove_dir_all(&dir);
    println!("{stats:?}");
    assert!(stats.findings.is_empty(), "{:#?}", stats.findings);
    // the mutator reaches both ends: renders and refusals, each a fair share
    assert!(stats.rendered > CASES / 10, "{stats:?}");
    assert!(stats.refused > CASES / 10, "{stats:?}");
}

/// Case `i` of a seed is the same case whenever it is made: a finding of the long run
/// can be made again from its number.
#[test]
fn cases_are_made_again_from_their_number() {
    for i in [0, 7, 123_456] {
        let (a, b) = (engine::case(9, i), engine::case(9, i));
        assert_eq!((a.scene, a.obj, a.profile), (b.scene, b.obj, b.profile));
    }
    assert_ne!(engine::case(9, 1).scene, engine::case(9, 2).scene);
}
