//! `Scenario::from_toml` on arbitrary text: never panics, and a scenario it accepts serialises
//! to TOML that parses back to the same scenario (a recording stores its scenario that way).
#![no_main]

use libfuzzer_sys::fuzz_target;
use proto::scenario::Scenario;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scenario) = Scenario::from_toml(text, "fuzz") {
        let again = Scenario::from_toml(&scenario.to_toml(), "fuzz (again)").expect("round trip");
        assert_eq!(again, scenario);
    }
});
