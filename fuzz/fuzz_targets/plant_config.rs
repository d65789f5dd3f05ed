//! The virtual actuator from what a user types or a file names: effect strings (`name:key=value,...`, arbitrary
//! text), parameter overrides by dotted name (known and unknown keys, any value), preset, sample rate and seed.
//! Every input gives an actuator or an error; an effect that parses prints as text that parses back to it; an
//! actuator that builds gives finite samples for any command (a non-finite command is applied as 0 A and flagged)
//! and replays bit for bit from its saved state.
#![no_main]
use bmr::plant::{Effect, EffectSet, PRESETS, SETTABLE, VirtualActuator, preset};
use bmr_fuzz::Reader;
use libfuzzer_sys::fuzz_target;

/// Text for an effect: mostly built from real names and keys, sometimes raw bytes.
fn effect_text(r: &mut Reader<'_>) -> String {
    if r.byte() % 4 == 0 {
        let n = r.count(40);
        let bytes: Vec<u8> = (0..n).map(|_| r.byte()).collect();
        return String::from_utf8_lossy(&bytes).into_owned();
    }
    let kinds = bmr::plant::EffectKind::ALL;
    let kind = kinds[r.count(kinds.len() - 1)];
    let mut text = String::from(kind.name());
    let specs = kind.params();
    let n = r.count(3);
    if n > 0 || r.byte() % 2 == 0 {
        text.push(':');
    }
    for i in 0..n {
        if i > 0 {
            text.push(',');
        }
        let key = if specs.is_empty() || r.byte() % 6 == 0 {
            "bogus"
        } else {
            specs[r.count(specs.len() - 1)].name
        };
        let value = match r.byte() % 5 {
            0 => String::from(["nan", "inf", "-inf", "1e999", "", "x", "0x10"][r.count(6)]),
            _ => format!("{}", r.float()),
        };
        text.push_str(&format!("{key}={value}"));
    }
    text
}

fuzz_target!(|data: &[u8]| {
    let mut r = Reader::new(data);
    let mut effects = Vec::new();
    for _ in 0..r.count(4) {
        let text = effect_text(&mut r);
        if let Ok(e) = Effect::parse(&text) {
            let printed = e.to_string();
            assert_eq!(
                Effect::parse(&printed).ok(),
                Some(e),
                "{text:?} printed as {printed:?} does not parse back"
            );
            effects.push(text);
        }
    }
    let Ok(set) = EffectSet::parse_all(&effects) else {
        return;
    };
    // Building an actuator costs milliseconds (two Preisach steels): one input in four goes on to build and run
    // one, so that the text parsing gets most of the executions (past the input's end bytes read as 0: no build).
    if r.byte() % 4 != 3 {
        return;
    }
    let mut config = preset(PRESETS[r.count(PRESETS.len() - 1)]).expect("preset");
    for e in set.iter() {
        config.effects.insert(*e);
    }
    for _ in 0..r.count(4) {
        let key = if r.byte() % 8 == 0 {
            "sensor.bogus"
        } else {
            SETTABLE[r.count(SETTABLE.len() - 1)]
        };
        let value = r.float();
        if config.set(key, value).is_err() {
            return;
        }
    }
    let seed = r.u64();
    let Ok(mut act) = VirtualActuator::new(config, seed) else {
        return;
    };
    let saved = act.save_state();
    let commands: Vec<f64> = (0..r.count(64))
        .map(|_| {
            if r.byte() % 8 == 0 {
                r.float()
            } else {
                4.0 * r.unit() - 2.0
            }
        })
        .collect();
    let mut first = Vec::with_capacity(commands.len());
    for &i in &commands {
        let s = act.step(i);
        assert_eq!(s.command_valid, i.is_finite(), "command {i} gave {s:?}");
        for v in [
            s.t_s,
            s.current_cmd_a,
            s.coil1_a,
            s.coil2_a,
            s.b1_t,
            s.b2_t,
            s.theta_rad,
            s.speed_rad_s,
            s.field_torque_nmm,
            s.friction_nmm,
            s.torque_true_nmm,
            s.torque_nmm,
        ] {
            assert!(v.is_finite(), "command {i} gave {s:?}");
        }
        first.push(s.torque_nmm.to_bits());
    }
    act.load_state(&saved).expect("own state");
    let again: Vec<u64> = commands
        .iter()
        .map(|&i| act.step(i).torque_nmm.to_bits())
        .collect();
    assert_eq!(first, again, "replay from the saved state differs");
});
