//! Runs of MCUs kept as they were between re-encoded ones: their bytes are copied when ZRL
//! codes align them, and they decode as when every bit is shifted.

use super::*;

#[test]
fn long_runs_of_kept_mcus_between_drawn_ones_keep_their_bytes() {
    // In 4:4:4 (8 px MCUs) and grey frames the overlay leaves runs of 8 MCUs or more
    // between drawn ones in a row; ZRLs align them and their bytes are copied. check_splice
    // compares the result, pixel for pixel, with the splice that shifts every bit.
    for grey in [false, true] {
        let jpeg = encode(
            Options {
                sampling: SamplingFactor::F_1_1,
                grey,
                ..COLOUR_420
            },
            |_| {},
        );
        let (spliced, error) = check_splice(&jpeg, 0);
        check_error(&jpeg, error, false);
        assert!(
            spliced.aligned_runs > 0,
            "grey {grey}: no run kept its bytes"
        );
    }
}
