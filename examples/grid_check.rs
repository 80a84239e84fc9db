fn main() {
    let mut cfg = psns::config::SceneConfig::default();
    for (name, att, zen) in [
        ("default", psns::camera::Attitude::default(), 50.0),
        (
            "tilted-horizon",
            psns::camera::Attitude::enu(30.0, 60.0, 0.0),
            50.0,
        ),
        (
            "sun-in-view",
            psns::camera::Attitude::enu(200.0, 40.0, 0.0),
            50.0,
        ),
    ] {
        cfg.camera.attitude = att;
        cfg.sun.zenith_deg = Some(zen);
        for r in psns::app::bench_sky_grid(&cfg, &[1, 2, 4, 8, 16], 3).unwrap() {
            println!("{name} {r:?}");
        }
    }
}
