use super::*;

fn tiny() -> DatasetConfig {
    DatasetConfig::from_toml(
        "seed = 7\nwidth = 64\nheight = 48\n[splits]\nNFPI = 3\nTGNIICPI = 2\n",
        "test",
    )
    .unwrap()
}

/// The `projection` and `lens` keys reach every sample's scene (and so its render); absent,
/// the projection is rectilinear and the lens each preset's; a bad name is refused by name.
#[test]
fn projection_and_lens_keys_reach_the_samples() {
    use crate::camera::{Lens, Projection};
    let t = tiny();
    let s = t.sample(Split::Nfpi, 1).unwrap().scene(Preset::Nfpi);
    assert_eq!(s.camera.intrinsics.projection, Projection::Rectilinear);
    assert_eq!(s.intrinsics().lens, Some(Lens::Pinhole));
    let d = DatasetConfig::from_toml(
        "seed = 7\nwidth = 64\nheight = 48\nprojection = \"equisolid\"\nlens = \"ideal\"\n[splits]\nNFPI = 1\n",
        "test",
    )
    .unwrap();
    let s = d.sample(Split::Nfpi, 1).unwrap().scene(Preset::Nfpi);
    assert_eq!(s.camera.intrinsics.projection, Projection::Equisolid);
    assert_eq!(s.intrinsics().lens, Some(Lens::Ideal));
    let back = DatasetConfig::from_toml(&d.to_toml(), "round trip").unwrap();
    assert_eq!(back, d);
    let e = DatasetConfig::from_toml("projection = \"fish\"\n", "bad")
        .unwrap_err()
        .to_string();
    assert!(e.contains("fish") && e.contains("equisolid"), "{e}");
}

#[test]
fn default_is_psns_at_full_size_and_round_trips() {
    let d = DatasetConfig::default();
    d.validate().unwrap();
    assert_eq!(d.total(), 138_000);
    assert_eq!((d.width, d.height), (2448, 2048));
    assert_eq!(d.split_counts().len(), 6);
    let back = DatasetConfig::from_toml(&d.to_toml(), "round trip").unwrap();
    assert_eq!(back, d);
    let t = tiny();
    assert_eq!(DatasetConfig::from_toml(&t.to_toml(), "x").unwrap(), t);
}

#[test]
fn draws_depend_on_seed_and_index_only() {
    let c = tiny();
    let plan = c.plan().unwrap();
    assert_eq!(plan.len(), 5);
    let all: Vec<Sample> = (0..5).map(|j| plan.sample(j).unwrap()).collect();
    // the same sample drawn alone, in another order, equals the one in the full list
    assert_eq!(c.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
    assert_eq!(all[4].frame_index, 5 * SPLIT_STRIDE + 2);
    // another split's count does not move this split's samples
    let mut c2 = c.clone();
    c2.splits.insert("NFPI".into(), 100);
    assert_eq!(c2.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
    // another seed does
    let mut c3 = c.clone();
    c3.seed = 8;
    assert_ne!(c3.sample(Split::Tgniicpi, 2).unwrap(), all[4]);
    // golden: the draw derivation is part of the dataset format
    assert_eq!(all[0].stem(), GOLDEN_STEM, "{}", all[0].stem());
    for s in &all {
        assert!((0.0..=359.9).contains(&s.yaw_deg));
        assert_eq!(s.yaw_deg, round_decimal(s.yaw_deg, 1));
        assert_eq!(s.albedo, round_decimal(s.albedo, 2));
        assert!((1.7..=10.0).contains(&s.turbidity));
    }
}
const GOLDEN_STEM: &str = "N1_172.8_0_0_4_16.4_8.8_392_0.2";

#[test]
fn grid_draws_cover_the_grid_and_print_as_decimals() {
    let d = uniform(1.7, 10.0, 0.1);
    let mut seen = std::collections::BTreeSet::new();
    for i in 0..20_000 {
        let mut r = crate::rng::dataset_rng(1, i, 7);
        let v = d.draw(&mut r, 0.5);
        assert!((1.7..=10.0).contains(&v), "{v}");
        let s = format!("{v}");
        assert!(decimals(v) <= 1 && !s.contains('e'), "{s}");
        seen.insert(s);
    }
    assert_eq!(seen.len(), 84); // 1.7, 1.8, ..., 10
    assert!(seen.contains("10") && seen.contains("1.7"));
    // a grid through zero from below never prints "-0"
    let d = uniform(-0.3, 0.3, 0.1);
    let mut seen = std::collections::BTreeSet::new();
    for i in 0..500 {
        let mut r = crate::rng::dataset_rng(1, i, 2);
        seen.insert(format!("{}", d.draw(&mut r, 0.1)));
    }
    assert_eq!(seen.len(), 7, "{seen:?}");
    assert!(seen.contains("0") && !seen.contains("-0"), "{seen:?}");
    assert_eq!(format!("{}", round_decimal(-1e-17, 1)), "0");
    let c = Dist::Choice(vec![400.0, 550.0]);
    let mut r = crate::rng::dataset_rng(1, 0, 8);
    assert!([400.0, 550.0].contains(&c.draw(&mut r, 1.0)));
}

#[test]
fn bad_descriptions_name_the_key_and_range() {
    let cases = [
        ("turbidty = 3\n", "turbidty"),
        (
            "[turbidity]\nmin = 1\nmax = 5\n",
            "turbidity.min = 1 is out of range (allowed 1.7..10)",
        ),
        (
            "[albedo]\nmin = 0.5\nmax = 0.2\n",
            "albedo.max = 0.2 is out of range (allowed 0.5..1)",
        ),
        ("[albedo]\nmin = 0\nmax = 1\nstp = 0.1\n", "stp"),
        (
            "wavelength_nm = 300\n",
            "wavelength_nm = 300 is out of range (allowed 380..720)",
        ),
        (
            "width = 66\n",
            "width = 66 is out of range (allowed a non-zero multiple of 4)",
        ),
        (
            "[splits]\nNFP = 3\n",
            "splits = NFP is out of range (allowed NFPI, GNIIPI, GNIICPI, TNFPI, TGNIIPI, TGNIICPI)",
        ),
        (
            "[splits]\n",
            "list at least one folder (NFPI, GNIIPI, GNIICPI, TNFPI, TGNIIPI, TGNIICPI)",
        ),
        (
            "[splits]\nNFPI = 0\n",
            "splits.NFPI = 0 is out of range (allowed 1..10000000)",
        ),
        ("sky_grid = 0\n", "sky_grid = 0"),
        ("[outputs]\nraw = true\n", "raw"),
        ("[yaw_deg]\nvalues = []\n", "yaw_deg.values is empty"),
        ("[yaw_deg]\nmin = 1\n", "max"),
        ("frame = \"ned\"\n", "ned"),
        ("[outputs]\nraw12_exposure_us = 500\n", "add raw12 = true"),
        (
            "soft_clouds = 1.5\n",
            "soft_clouds = 1.5 is out of range (allowed 0..1)",
        ),
        (
            "[outputs]\nraw12 = true\nraw12_exposure_us = 5\n",
            "outputs.raw12_exposure_us = 5 is out of range (allowed 20..10000000)",
        ),
    ];
    for (text, want) in cases {
        let e = DatasetConfig::from_toml(text, "c.toml").unwrap_err();
        assert!(e.is_usage(), "{text}: {e}");
        assert!(e.to_string().contains(want), "{text}: {e}");
    }
}

#[test]
fn shard_parsing_and_partition() {
    assert_eq!("2/3".parse::<Shard>().unwrap(), Shard { k: 2, n: 3 });
    for bad in ["0/3", "4/3", "3", "a/b", "1/0", "-1/3", "1/2000000"] {
        let e = bad.parse::<Shard>().unwrap_err();
        assert!(
            e.is_usage() && e.to_string().contains("1 <= K <= N"),
            "{bad}: {e}"
        );
    }
    // every position in exactly one of N shards
    for j in 0..30 {
        let owners = (1..=4).filter(|&k| Shard { k, n: 4 }.contains(j)).count();
        assert_eq!(owners, 1);
    }
}

#[test]
fn label_row_has_every_column_and_the_scene_matches() {
    let c = tiny();
    let s = c.sample(Split::Nfpi, 1).unwrap();
    let row = s.label_row().unwrap();
    assert_eq!(row.split(',').count(), LABEL_HEADER.split(',').count());
    assert!(row.starts_with(&format!("NFPI,NFPI/{}.png,", s.stem())));
    let v = s.sun_camera();
    assert!((v.length() - 1.0).abs() < 1e-12);
    let scene = s.scene(Preset::Nfpi);
    assert_eq!(scene.sun.resolve().unwrap(), s.sun());
    assert_eq!(scene.raw.frame_index, s.frame_index);
}

#[test]
fn sun_from_times_and_places() {
    let text = "width = 64\nheight = 48\n[splits]\nNFPI = 20\n[sun_time]\nstart = \"2024-06-01T00:00:00Z\"\nend = \"2024-06-30T23:59:59Z\"\nlat_deg = 45\nlon_deg = { min = 0, max = 10 }\nmin_altitude_deg = 20\n";
    let c = DatasetConfig::from_toml(text, "t").unwrap();
    assert_eq!(DatasetConfig::from_toml(&c.to_toml(), "again").unwrap(), c);
    let plan = c.plan().unwrap();
    for s in c.samples().map(Result::unwrap) {
        assert_eq!(plan.sample(s.number - 1).unwrap(), s);
        let w = s.when.as_ref().unwrap();
        assert!(s.sun_altitude_deg >= 20.0 && s.sun_altitude_deg <= 90.0);
        assert_eq!(s.sun_altitude_deg, round_decimal(s.sun_altitude_deg, 3));
        // the label's sun is SPA's for the label's time and place, to 0.001 degree
        let t = crate::sun::parse_time(&w.time_utc).unwrap();
        let place = crate::sun::Place {
            lat_deg: w.lat_deg,
            lon_deg: w.lon_deg,
            height_m: 0.0,
        };
        let sun = crate::sun::spa(&t, &place, None, None).unwrap();
        assert!((90.0 - sun.zenith_deg - s.sun_altitude_deg).abs() <= 0.0005);
        assert!((sun.azimuth_deg - s.sun_azimuth_deg).abs() <= 0.0005);
        assert_eq!(w.lat_deg, 45.0);
        assert!(w.time_utc.starts_with("2024-06-"), "{}", w.time_utc);
        let row = s.label_row().unwrap();
        assert!(
            row.contains(&format!(",{},45,{},,0,", w.time_utc, w.lon_deg)),
            "{row}"
        );
    }
    // a polar night never has the sun up: refused, naming the key
    let polar = text.replace("lat_deg = 45", "lat_deg = -85");
    let c = DatasetConfig::from_toml(&polar, "t").unwrap();
    let e = c.plan().unwrap_err().to_string();
    assert!(
        e.contains("NFPI sample 1: sun_time: the sun was below min_altitude_deg = 20"),
        "{e}"
    );
    // both ways of giving the sun, a bad time, an end before the start
    let both = format!("sun_altitude_deg = 30\n{text}");
    let e = DatasetConfig::from_toml(&both, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("either by sun_time or by sun_altitude_deg"),
        "{e}"
    );
    let bad = text.replace("2024-06-01T00:00:00Z", "June 1st");
    let e = DatasetConfig::from_toml(&bad, "t").unwrap_err().to_string();
    assert!(e.contains("sun_time.start: time 'June 1st'"), "{e}");
    let back = text.replace("2024-06-30T23:59:59Z", "2024-05-30T23:59:59Z");
    let e = DatasetConfig::from_toml(&back, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("sun_time.end = 2024-05-30T23:59:59Z is out of range"),
        "{e}"
    );
    let e = DatasetConfig::from_toml(&text.replace("= 45", "= 95"), "t").unwrap_err();
    assert!(e
        .to_string()
        .contains("sun_time.lat_deg = 95 is out of range (allowed -90..90)"));
}

/// The plan as it was before samples were drawn on demand: every sample drawn up front, in
/// canonical order. Kept here only as the oracle of [`Plan`].
fn eager_plan(c: &DatasetConfig) -> Result<Vec<Sample>> {
    let ids: Vec<(Split, u64)> = c
        .split_counts()
        .into_iter()
        .flat_map(|(s, n)| (1..=n).map(move |k| (s, k)))
        .collect();
    ids.iter().map(|&(s, k)| c.sample(s, k)).collect()
}

/// `labels.csv` as the build wrote it from the eager plan: held whole in memory.
fn eager_labels(c: &DatasetConfig, plan: &[Sample]) -> String {
    let mut labels = String::new();
    labels.push_str(LABEL_HEADER);
    labels.push('\n');
    for s in plan {
        labels.push_str(&s.label_row_with(c.outputs.raw12).unwrap());
        labels.push('\n');
    }
    labels
}

/// A description drawn from the parameters of a proptest case: a subset of the splits with
/// small counts, seed, distributions, clouds, the 12-bit frame's exposure and the sun from
/// times and places.
fn random_description(
    seed: u64,
    counts: [u64; 6],
    yaw_step: f64,
    clouds: f64,
    raw12: bool,
    sun_time: bool,
) -> DatasetConfig {
    let mut c = DatasetConfig {
        seed,
        width: 64,
        height: 48,
        yaw_deg: uniform(-30.0, 30.0, yaw_step),
        pitch_deg: Dist::Choice(vec![-2.5, 0.0, 7.25]),
        roll_deg: Dist::Uniform {
            min: -1.0,
            max: 1.0,
            step: Some(0.0),
        },
        soft_clouds: clouds,
        ..Default::default()
    };
    c.splits = Split::ALL
        .iter()
        .zip(counts)
        .filter(|&(_, n)| n > 0)
        .map(|(s, n)| (s.name().to_string(), n))
        .collect();
    if c.splits.is_empty() {
        c.splits.insert("TGNIIPI".into(), 3);
    }
    c.outputs.raw12 = raw12;
    if raw12 {
        c.outputs.raw12_exposure_us = Some(uniform(100.0, 5000.0, 10.0));
    }
    if sun_time {
        c.sun_time = Some(SunTime {
            start: "2024-03-01T00:00:00Z".into(),
            end: "2024-09-30T23:59:59Z".into(),
            lat_deg: uniform(-40.0, 40.0, 0.01),
            lon_deg: default_lon(),
            min_altitude_deg: 5.0,
        });
    }
    c.validate().unwrap();
    c
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
    /// Sample `j` drawn on demand is sample `j` of the eager plan, the labels written as the
    /// plan is walked are the eager labels byte for byte, and a shard's positions are those of
    /// `Shard::contains`, for random descriptions, seeds and shards.
    #[test]
    fn lazy_plan_equals_the_eager_plan(
        seed in proptest::prelude::any::<u64>(),
        counts in proptest::array::uniform6(0u64..40),
        yaw_step in proptest::sample::select(vec![0.0, 0.1, 0.25, 1.0]),
        clouds in proptest::sample::select(vec![0.0, 0.3, 1.0]),
        raw12 in proptest::prelude::any::<bool>(),
        sun_time in proptest::prelude::any::<bool>(),
        shard_n in 1u64..9,
        shard_k in 1u64..9,
    ) {
        let c = random_description(seed, counts, yaw_step, clouds, raw12, sun_time);
        let eager = eager_plan(&c).unwrap();
        let plan = c.plan().unwrap();
        proptest::prop_assert_eq!(plan.len(), eager.len() as u64);
        for (j, s) in eager.iter().enumerate() {
            proptest::prop_assert_eq!(&plan.sample(j as u64).unwrap(), s);
            proptest::prop_assert_eq!(plan.id(j as u64), (s.split, s.number));
        }
        let mut labels = Vec::new();
        plan.write_labels(&mut labels, std::path::Path::new("labels.csv")).unwrap();
        proptest::prop_assert_eq!(String::from_utf8(labels).unwrap(), eager_labels(&c, &eager));
        let shard = Shard { k: shard_k.min(shard_n), n: shard_n };
        let lazy: Vec<u64> = {
            use rayon::prelude::*;
            plan.shard_positions(shard).collect()
        };
        let old: Vec<u64> = (0..eager.len() as u64).filter(|&j| shard.contains(j)).collect();
        proptest::prop_assert_eq!(lazy, old);
    }
}

/// A plan is the description and one entry per split, whatever the number of samples: six
/// splits at the cap (60,000,000 samples) plan instantly in a few hundred bytes, and any
/// position maps to its split and number (the eager plan took about 850 bytes a sample).
#[test]
fn a_plan_holds_nothing_per_sample() {
    use rayon::prelude::*;
    let mut c = tiny();
    c.splits = Split::ALL
        .iter()
        .map(|s| (s.name().to_string(), MAX_SAMPLES_PER_SPLIT))
        .collect();
    c.validate().unwrap();
    let plan = c.plan().unwrap();
    let n = MAX_SAMPLES_PER_SPLIT;
    assert_eq!(plan.len(), 6 * n);
    // what the plan owns besides the description: its fixed fields and one entry per split
    let owned = std::mem::size_of_val(&plan) + 6 * std::mem::size_of::<(Split, u64, u64)>();
    assert!(owned < 512, "{owned} bytes");
    for (i, s) in Split::ALL.into_iter().enumerate() {
        let first = i as u64 * n;
        assert_eq!(plan.id(first), (s, 1));
        assert_eq!(plan.id(first + n - 1), (s, n));
        assert_eq!(plan.sample(first + n - 1).unwrap(), c.sample(s, n).unwrap());
    }
    let mut rng = crate::rng::dataset_rng(3, 0, 0);
    for _ in 0..200 {
        let j = rng.random_range(0..6 * n);
        let (s, k) = plan.id(j);
        assert_eq!(s.id() * n + k - 1, j);
        assert_eq!(
            plan.sample(j).unwrap().frame_index,
            s.id() * SPLIT_STRIDE + k
        );
    }
    let shard = Shard {
        k: 17,
        n: MAX_SHARDS,
    };
    assert_eq!(plan.shard_positions(shard).len(), 60);
    let last: Vec<u64> = plan.shard_positions(shard).collect();
    assert_eq!(last.last(), Some(&(59 * MAX_SHARDS + 16)));
    // walking a plan holds one chunk of drawn samples at a time, in order
    let mut c = tiny();
    c.splits = [("NFPI".to_string(), 20_000)].into();
    let mut next = 1;
    c.plan()
        .unwrap()
        .walk(
            |s| s.number,
            |k| {
                assert_eq!(k, next);
                next += 1;
                Ok(())
            },
        )
        .unwrap();
    assert_eq!(next, 20_001);
}

/// A world preset sets only the world keys the description leaves out, and the description
/// with them written out reads back the same; each world number has its own stream, so fixing
/// one never changes another's draws; without world keys the world's columns are empty.
#[test]
fn world_presets_fill_missing_keys_and_world_draws_are_independent() {
    let base = "seed = 3\nwidth = 64\nheight = 48\n[splits]\nNFPI = 20\n";
    let c = DatasetConfig::from_toml(&format!("world = \"urban\"\ncloud_cover = 0\n{base}"), "t")
        .unwrap();
    assert_eq!(c.world, Some(WorldPreset::Urban));
    assert_eq!(c.cloud_cover, Some(Dist::Fixed(0.0)));
    assert_eq!(c.camera_height_m, Some(Dist::Fixed(1.5)));
    assert_eq!(c.canyon.as_ref().unwrap().width_m, uniform(10.0, 50.0, 0.5));
    assert!(c.trees.is_none());
    assert_eq!(DatasetConfig::from_toml(&c.to_toml(), "again").unwrap(), c);
    let mut other = c.clone();
    other.camera_height_m = Some(Dist::Fixed(3.0));
    let mut widths = std::collections::BTreeSet::new();
    for n in 1..=20 {
        let (a, b) = (
            c.sample(Split::Nfpi, n).unwrap(),
            other.sample(Split::Nfpi, n).unwrap(),
        );
        let (wa, wb) = (a.world.unwrap(), b.world.unwrap());
        assert_eq!(wa.canyon, wb.canyon);
        assert_eq!((wa.camera_height_m, wb.camera_height_m), (1.5, 3.0));
        let cy = wa.canyon.unwrap();
        assert!((10.0..=50.0).contains(&cy.width_m) && (4.0..=30.0).contains(&cy.height_m));
        assert!((0.0..=179.9).contains(&cy.azimuth_deg));
        widths.insert(cy.width_m.to_string());
    }
    assert!(widths.len() > 5, "{widths:?}");
    let canopy = DatasetConfig::from_toml(&format!("world = \"canopy\"\n{base}"), "t").unwrap();
    for n in 1..=20 {
        let w = canopy.sample(Split::Nfpi, n).unwrap().world.unwrap();
        assert!((2..=6).contains(&w.trees.len()), "{}", w.trees.len());
        for t in &w.trees {
            let d = t.east_m.hypot(t.north_m);
            assert!((1.0 - 1e-9..=10.0 + 1e-9).contains(&d), "{d}");
        }
    }
    let plain = DatasetConfig::from_toml(base, "t").unwrap();
    let s = plain.sample(Split::Nfpi, 1).unwrap();
    assert!(s.world.is_none());
    let empty = ",".repeat(WORLD_LABEL_HEADER.matches(',').count() + 1);
    assert!(s
        .label_row()
        .unwrap()
        .ends_with(&format!("wang-bounded,25,25{empty}")));
    assert!(LABEL_HEADER.ends_with(&format!(",{WORLD_LABEL_HEADER}")));
    let strides = [(64, 48), (128, 128), (129, 128), (2448, 2048)]
        .map(|(w, h)| crate::render::class_stride(w, h));
    assert_eq!(strides, [1, 1, 2, 18]);
}
