//! The supervisor on real (tiny) child processes.

use super::*;

fn sh(script: &'static str) -> MakeCommand {
    Box::new(move || {
        let mut cmd = Command::new("sh");
        cmd.args(["-c", script]);
        Ok(cmd)
    })
}

#[allow(clippy::disallowed_methods)] // tests drive the supervisor's clock from the real one
fn now() -> Instant {
    Instant::now()
}

/// Watch until `done` says so or 5 s passed; every event seen.
fn watch_until(sup: &mut Supervisor, done: impl Fn(&[Event]) -> bool) -> Vec<Event> {
    let deadline = now() + Duration::from_secs(5);
    let mut events = Vec::new();
    while now() < deadline && !done(&events) {
        events.extend(sup.watch(now()));
        std::thread::sleep(Duration::from_millis(10));
    }
    events
}

#[test]
fn stop_terminates_and_reaps_children_and_kills_those_ignoring_sigterm() {
    let mut sup = Supervisor::new(Duration::from_millis(300), None);
    sup.spawn("polite", sh("sleep 30"), now()).unwrap();
    sup.spawn("stubborn", sh("trap '' TERM; sleep 30 & wait"), now())
        .unwrap();
    std::thread::sleep(Duration::from_millis(100));
    let killed = sup.stop_all();
    assert_eq!(killed, vec!["stubborn".to_string()]);
    for c in sup.children_mut() {
        assert!(!c.running(), "{} was not reaped", c.name);
    }
}

#[test]
fn without_a_policy_a_crashed_child_is_reported_once_and_left_alone() {
    let mut sup = Supervisor::new(Duration::from_millis(100), None);
    sup.spawn("crasher", sh("exit 3"), now()).unwrap();
    let events = watch_until(&mut sup, |e| !e.is_empty());
    assert_eq!(events.len(), 1, "{events:?}");
    let Event::Ended {
        status, restart_in, ..
    } = &events[0]
    else {
        panic!("{events:?}")
    };
    assert_eq!(status.code(), Some(3));
    assert_eq!(*restart_in, None);
    assert_eq!(events[0].to_string(), "crasher ended (exit code 3)");
    assert!(sup.watch(now()).is_empty());
}

#[test]
fn a_crashed_child_is_restarted_with_growing_delays_then_given_up_on() {
    let policy = RestartPolicy {
        first_delay: Duration::from_millis(20),
        max_delay: Duration::from_millis(50),
        stable_after: Duration::from_secs(60),
        max_in_a_row: 3,
    };
    let mut sup = Supervisor::new(Duration::from_millis(100), Some(policy));
    sup.spawn("crasher", sh("exit 7"), now()).unwrap();
    let events = watch_until(&mut sup, |e| e.iter().any(|e| matches!(e, Event::GaveUp { .. })));
    let delays: Vec<Duration> = events
        .iter()
        .filter_map(|e| match e {
            Event::Ended {
                restart_in: Some(d), ..
            } => Some(*d),
            _ => None,
        })
        .collect();
    assert_eq!(
        delays,
        [20, 40, 50].map(Duration::from_millis),
        "doubling, capped: {events:?}"
    );
    let restarts = events
        .iter()
        .filter(|e| matches!(e, Event::Restarted { .. }))
        .count();
    assert_eq!(restarts, 3);
    let said: Vec<String> = events.iter().map(ToString::to_string).collect();
    assert!(
        said.iter()
            .any(|s| s == "crasher ended (exit code 7); restarting it in 0.0 s"
                || s.starts_with("crasher ended (exit code 7); restarting it in")),
        "{said:?}"
    );
    assert!(
        said.iter().any(|s| s.starts_with("crasher restarted as pid")),
        "{said:?}"
    );
    assert!(
        said.last()
            .unwrap()
            .starts_with("crasher gave up after 3 restarts"),
        "{said:?}"
    );
    assert!(sup.watch(now() + Duration::from_secs(60)).is_empty());
}

#[test]
fn a_killed_child_comes_back_and_stop_calls_off_a_pending_restart() {
    let policy = RestartPolicy {
        first_delay: Duration::from_millis(10),
        ..RestartPolicy::default()
    };
    let mut sup = Supervisor::new(Duration::from_millis(300), Some(policy));
    let first = sup.spawn("sleeper", sh("sleep 30"), now()).unwrap().pid();
    signal_group(first, libc::SIGKILL);
    let events = watch_until(&mut sup, |e| {
        e.iter().any(|e| matches!(e, Event::Restarted { .. }))
    });
    let second = sup.get_mut("sleeper").unwrap().pid();
    assert_ne!(first, second, "{events:?}");
    assert!(events[0].to_string().contains("killed by signal 9"), "{events:?}");
    assert!(sup.get_mut("sleeper").unwrap().running());
    // Ended again, restart pending: stopping now leaves it ended.
    signal_group(second, libc::SIGKILL);
    let _ = watch_until(&mut sup, |e| e.iter().any(|e| matches!(e, Event::Ended { .. })));
    assert!(sup.stop_all().is_empty());
    assert!(sup.watch(now() + Duration::from_secs(60)).is_empty());
    assert!(!sup.get_mut("sleeper").unwrap().running());
}

#[test]
fn the_delay_doubles_up_to_its_cap() {
    let p = RestartPolicy::default();
    assert_eq!(p.delay(1), Duration::from_millis(500));
    assert_eq!(p.delay(2), Duration::from_secs(1));
    assert_eq!(p.delay(4), Duration::from_secs(4));
    assert_eq!(p.delay(40), Duration::from_secs(30));
}

#[test]
fn chaos_kills_are_restarted_at_once_and_never_count_towards_giving_up() {
    let policy = RestartPolicy {
        first_delay: Duration::from_millis(10),
        max_delay: Duration::from_millis(20),
        stable_after: Duration::from_secs(60),
        max_in_a_row: 2,
    };
    let mut sup = Supervisor::new(Duration::from_millis(300), Some(policy));
    sup.spawn("victim", sh("sleep 30"), now()).unwrap();
    // Twice the number of restarts that would give up on a crashing child.
    for _ in 0..4 {
        let before = sup.get_mut("victim").unwrap().pid();
        let Some(Event::ChaosKilled { pid, restart_in, .. }) = sup.chaos_kill("victim", now()) else {
            panic!("a running child is killed");
        };
        assert_eq!((pid, restart_in), (before, policy.first_delay));
        let events = watch_until(&mut sup, |e| {
            e.iter().any(|e| matches!(e, Event::Restarted { .. }))
        });
        assert!(
            matches!(
                events[..],
                [Event::Restarted {
                    n: 0,
                    after_chaos: true,
                    ..
                }]
            ),
            "{events:?}"
        );
        assert!(events[0].to_string().contains("after a chaos kill"));
        assert_ne!(sup.get_mut("victim").unwrap().pid(), before);
    }
    assert_eq!(sup.get_mut("victim").unwrap().restarts, 4);
    // A real crash still counts: killed from outside, it is restart 1 in a row.
    signal_group(sup.get_mut("victim").unwrap().pid(), libc::SIGKILL);
    let events = watch_until(&mut sup, |e| {
        e.iter().any(|e| matches!(e, Event::Restarted { .. }))
    });
    assert!(
        events.iter().any(|e| matches!(
            e,
            Event::Restarted {
                n: 1,
                after_chaos: false,
                ..
            }
        )),
        "{events:?}"
    );
    // Not running (restart pending) or unknown: nothing to kill.
    assert!(sup.chaos_kill("nobody", now()).is_none());
    assert!(sup.chaos_kill("victim", now()).is_some());
    assert!(sup.chaos_kill("victim", now()).is_none());
    sup.stop_all();
}

#[test]
fn without_a_restart_policy_there_is_no_chaos() {
    let mut sup = Supervisor::new(Duration::from_millis(300), None);
    sup.spawn("calm", sh("sleep 30"), now()).unwrap();
    assert!(sup.chaos_kill("calm", now()).is_none());
    assert!(sup.get_mut("calm").unwrap().running());
    sup.stop_all();
}
