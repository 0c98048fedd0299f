use super::*;
use proto::msg::PixelBox;
use proto::observation::Kinds;
use proto::scenario::Scenario;

fn person(x: f64, y: f64) -> GroundPoint {
    GroundPoint {
        local: 0,
        position: [x, y],
        cov: [0.04, 0.0, 0.04],
        width_m: 0.5,
        height_m: 1.8,
        confidence: 0.5,
        histogram: Vec::new(),
        captured: ClusterTime::ZERO,
        ml_position: [x as f32, y as f32],
    }
}

fn prior(x: f64, y: f64) -> Prior {
    Prior {
        target: TargetId(1),
        step: 1,
        mean: models::vec6_to_wire(&State::new(x, y, 0.9, 0.0, 0.0, 0.0)),
        cov: models::mat6_to_wire(&(nalgebra::Matrix6::identity() * 0.05)),
        deadline: ClusterTime::ZERO,
    }
}

#[test]
fn ground_points_gate_one_to_one_in_the_floor_plane() {
    let (a, b) = (prior(2.0, 2.0), prior(5.0, 3.0));
    let people = [person(5.1, 3.0), person(2.0, 2.1), person(9.0, 1.0)];
    let got = associate(&[(&a, 0.0), (&b, 0.0)], &people, 13.8);
    assert_eq!(got, vec![Some(1), Some(0), None]);
    assert_eq!(nearest(&a, &people, 0.0, 13.8), Some(&people[1]));
    assert_eq!(nearest(&prior(7.0, 6.0), &people, 0.0, 13.8), None);
}

#[test]
fn a_contribution_folds_the_floor_position_and_the_centre_height() {
    let p = prior(2.0, 2.0);
    let c = contribution(
        &p,
        Some(&person(2.1, 2.0)),
        ClusterTime::ZERO,
        0.0,
        Mode::Active,
        &[],
    );
    assert_eq!(c.folded, Kinds::of(ObservationKind::Ground));
    assert!((c.info_matrix[0][0] - 25.0).abs() < 1e-9, "1 / 0.04 m²");
    assert!(c.info_matrix[2][2] > 0.0);
    let none = contribution(&p, None, ClusterTime::ZERO, 0.0, Mode::Active, &[]);
    assert!(none.folded.is_empty());
    let m = measurement(
        &Scenario::default_scenario().camera_model(10).unwrap(),
        person(1.0, 1.0),
        None,
        Mode::Active,
        &[],
    );
    assert!(matches!(m.observations[..], [Observation::Ground(_)]));
}

#[test]
fn projected_boxes_become_ground_points_and_boxes_above_the_horizon_are_dropped() {
    let cam = Scenario::default_scenario().camera_model(10).unwrap();
    let mut people = GroundPeople::new(&ParticleParams::default(), 1).unwrap();
    let det = |ymin: f32, ymax: f32| Detection {
        centre: [176.0, 0.5 * (ymin + ymax)],
        foot: [176.0, ymax],
        bbox: PixelBox {
            xmin: 160.0,
            ymin,
            xmax: 192.0,
            ymax,
        },
        area: 1000,
        colour: proto::msg::ColourSignature {
            hue: 0.0,
            saturation: 0.0,
            intensity: 0.5,
        },
    };
    people.from_boxes(&cam, &[det(120.0, 200.0), det(-400.0, -300.0)], ClusterTime::ZERO);
    assert_eq!(people.latest().len(), 1);
    let g = &people.latest()[0];
    assert!(g.histogram.is_empty() && g.width_m > 0.0 && g.height_m > 0.0);
    assert!(g.cov[0] >= GROUND_POSITION_FLOOR_M2);
    assert!(
        people.samples(None).is_empty(),
        "no filters run on projected boxes"
    );
}
