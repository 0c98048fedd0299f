//! A small scenario for unit tests: server 1, head 2 covering `[0, 6] × [0, 8]`, head 3
//! covering `[6, 12] × [0, 8]`, camera 10 in cluster 2, camera 11 in cluster 3, one target
//! walking a loop across both regions at 1 m/s.

use proto::scenario::Scenario;

pub const TOML: &str = r#"
name = "server-test"
[world]
min = [0.0, 0.0, 0.0]
max = [12.0, 8.0, 3.0]
[network]
transport = "tcp"
domain = "test"
heartbeat-ms = 200
liveness-timeout-ms = 1000
sync-beacon-ms = 1000
queue-len = 64
[[nodes]]
id = 1
role = "server"
[[nodes]]
id = 2
role = "head"
region = [0.0, 0.0, 6.0, 8.0]
[[nodes]]
id = 3
role = "head"
region = [6.0, 0.0, 12.0, 8.0]
[[nodes]]
id = 10
role = "camera"
head = 2
camera.intrinsics = { fx = 320.0, fy = 320.0, cx = 176.0, cy = 144.0, width = 352, height = 288 }
camera.pose = { rvec = [0.0, 0.0, 0.0], tvec = [0.0, 0.0, 3.0] }
[[nodes]]
id = 11
role = "camera"
head = 3
camera.intrinsics = { fx = 320.0, fy = 320.0, cx = 176.0, cy = 144.0, width = 352, height = 288 }
camera.pose = { rvec = [0.0, 0.0, 0.0], tvec = [-6.0, 0.0, 3.0] }
[[targets]]
id = 1
size = [0.4, 0.4, 1.0]
colour = [200, 30, 30]
trajectory = { kind = "loop", waypoints = [[2.0, 4.0], [10.0, 4.0]], speed = 1.0 }
"#;

pub fn scenario() -> Scenario {
    Scenario::from_toml(TOML, "<server-test>").expect("the test scenario is valid")
}
