//! `psns bench heading --budget`: what each part of the chain costs a heading estimate.
//!
//! Every estimator assumes a sky: the eigenvector method Rayleigh's (E ⟂ sun), the model fit
//! Berry's field with free neutral-point distances, Hough a field whose E-vector is perpendicular
//! to the solar meridian on it (Rayleigh's). Each source of error is measured alone against the
//! estimator's own sky rendered ideally (truth AoLP/DoLP, exact tilt, the lens it assumes), as the
//! per-frame change of the yaw error it causes (paired frames: same sun, yaw, tilt):
//!
//! * sky-model mismatch: ideal images of every other polarization model, and of the "field sky"
//!   (asymmetric neutral points at Pan's distances, peak DOP 0.8);
//! * demosaic: an ideal mosaic (every sensor stage off, unrounded) through each demosaic method;
//! * shot/read noise: shot, read and dark noise on that mosaic (unrounded, bilinear), minus the
//!   mosaic without them; quantisation: the 12-bit ADC alone, likewise; fixed patterns and
//!   optics: PRNU, DSNU, the polarizers' extinction and orientation errors, crosstalk and
//!   vignetting, likewise;
//! * IMU tilt error: the estimator told pitch and roll with N(0, 0.5°) errors;
//! * lens model: the estimator's focal length 0.5 % long and principal point 3 pixels of the full
//!   sensor off (an ordinary calibration error), and separately the pinhole polarization
//!   transport (PSNS eqs. (19)–(20)) assumed for the real (ideal) lens;
//! * clouds: 20 soft unpolarized patches, with the shot/read noise (on noise-free images clouds
//!   lower the DoLP but leave the AoLP alone), minus the noisy frames without them.
//!
//! End to end: the field sky, every sensor stage, 12 bit, bilinear, the IMU and calibration
//! errors together; again under each polarization model, with each other demosaic method, with
//! clouds, under CIE radiance (types 1, 7, 12, 15), and without the IMU and calibration errors. All frames: 612 × 512 at 13.8 µm (the full sensor's field of view),
//! camera preset with auto-exposure and no sun disc, pitch 5° and roll −5° (compensated), sun
//! elevation 15°, 35°, 55° at azimuth 200°, yaws 17° + 90° k.

use super::demosaic::BenchFiles;
use super::heading::csv_field;
use psns::camera::{Attitude, Intrinsics, Lens};
use psns::config::SceneConfig;
use psns::demosaic::{full_chain, Method, PolarImages};
use psns::heading::polar_from_codes;
use psns::heading::{
    error_stats, estimate_heading_info, wrap180, HeadingMethod, HeadingSetup, PolarView,
};
use psns::image::Image;
use psns::pipeline::{FrameRequest, RawPipeline};
use psns::sensor::{Exposure, SensorConfig, Stages};
use psns::sky::cie::Radiance;
use psns::sky::clouds::SoftClouds;
use psns::sky::{PolarizationModel, SkyParams};
use psns::sun::SunPosition;
use psns::{Error, Result};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::collections::HashMap;
use std::path::PathBuf;

/// Options of `psns bench heading --budget`.
#[derive(Clone, Debug)]
pub struct BudgetOptions {
    /// Output directory.
    pub out: PathBuf,
    /// 304 × 256 frames, one sun, two yaws (refused with an --out inside docs/).
    pub quick: bool,
}

/// Sun azimuth of every frame (compass degrees).
const SUN_AZIMUTH: f64 = 200.0;
/// Camera tilt of every frame (pitch, roll), compensated by the estimator.
const TILT: (f64, f64) = (5.0, -5.0);
/// Standard deviation of the IMU's pitch and roll errors, degrees.
pub const IMU_SIGMA_DEG: f64 = 0.5;
/// Relative error of the estimator's focal length.
pub const FOCAL_ERROR: f64 = 0.005;
/// Error of the estimator's principal point (both axes), pixels of the full 3.45 µm sensor.
pub const PRINCIPAL_POINT_ERROR_PX: f64 = 3.0;
/// Peak DOP of the field sky (real clear skies peak near 0.8).
pub const FIELD_DOP_MAX: f64 = 0.8;
/// CIE radiance types of the end-to-end rows.
const CIE_TYPES: [u8; 4] = [1, 7, 12, 15];

/// The sky an estimator assumes.
fn own_model(m: HeadingMethod) -> PolarizationModel {
    match m {
        HeadingMethod::ModelFit => PolarizationModel::Berry,
        _ => PolarizationModel::Rayleigh,
    }
}

/// A sky of the budget: a model with its defaults, or the field sky.
#[derive(Clone, Copy, Debug, PartialEq)]
enum SkyKind {
    Model(PolarizationModel),
    Field,
}

impl SkyKind {
    fn label(self) -> String {
        match self {
            SkyKind::Model(m) => m.name().to_string(),
            SkyKind::Field => "field (asymmetric; Pan; DOP 0.8)".into(),
        }
    }

    fn params(self) -> SkyParams {
        match self {
            SkyKind::Model(m) => SkyParams {
                model: m,
                ..SkyParams::default()
            },
            SkyKind::Field => SkyParams {
                model: PolarizationModel::Asymmetric,
                dop_max: FIELD_DOP_MAX,
                ..SkyParams::default()
            },
        }
    }
}

/// How a frame's AoLP/DoLP images are made.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Chain {
    /// Truth Stokes straight to AoLP/DoLP.
    Ideal,
    /// A mosaic with these sensor stages (quantize off: unrounded), demosaicked.
    Sensor(Stages, Method),
}

/// What the estimator is told, apart from the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Told {
    Truth,
    ImuError,
    Calibration,
    PinholeLens,
    /// IMU and calibration errors together (end to end).
    Both,
}

/// One scenario: its row labels, the sky, clouds and radiance, the image chain, what the
/// estimator is told, the methods it is run for, and the scenario its errors are paired with.
#[derive(Clone, Debug)]
struct Scenario {
    source: String,
    detail: String,
    sky: SkyKind,
    clouds: bool,
    radiance: Radiance,
    chain: Chain,
    told: Told,
    methods: Vec<HeadingMethod>,
    /// Key of the paired reference per method (`None`: the error itself).
    reference: Option<fn(HeadingMethod) -> String>,
}

impl Scenario {
    fn key(&self) -> String {
        format!("{}|{}", self.source, self.detail)
    }
}

fn stages_none() -> Stages {
    Stages::none()
}

fn noise_stages() -> Stages {
    Stages {
        shot: true,
        read: true,
        dark: true,
        ..Stages::none()
    }
}

fn adc_stages() -> Stages {
    Stages {
        quantize: true,
        fwc_clip: true,
        ..Stages::none()
    }
}

fn fixed_stages() -> Stages {
    Stages {
        prnu: true,
        dsnu: true,
        polarizer_er: true,
        polarizer_orientation: true,
        crosstalk: true,
        ri: true,
        ..Stages::none()
    }
}

/// The reference of the sensor sources: the ideal mosaic through bilinear, on the own sky.
fn ref_mosaic(m: HeadingMethod) -> String {
    format!("demosaic|bilinear ({})", own_model(m).name())
}

/// The reference of the clouds: the noisy mosaic through bilinear, on the own sky.
fn ref_noise(m: HeadingMethod) -> String {
    format!("shot/read noise|bilinear ({})", own_model(m).name())
}

/// The reference of the other sources: the ideal images of the own sky.
fn ref_ideal(m: HeadingMethod) -> String {
    format!("ideal|own sky ({})", own_model(m).name())
}

/// Every scenario of the budget.
fn scenarios() -> Vec<Scenario> {
    let all = HeadingMethod::ALL.to_vec();
    let owners = |sky: PolarizationModel| -> Vec<HeadingMethod> {
        HeadingMethod::ALL
            .into_iter()
            .filter(|&m| own_model(m) == sky)
            .collect()
    };
    let own_skies = [PolarizationModel::Rayleigh, PolarizationModel::Berry];
    let mut v = Vec::new();
    let base = |source: &str, detail: String, sky: SkyKind| Scenario {
        source: source.into(),
        detail,
        sky,
        clouds: false,
        radiance: Radiance::Hosek,
        chain: Chain::Ideal,
        told: Told::Truth,
        methods: Vec::new(),
        reference: None,
    };
    for s in own_skies {
        v.push(Scenario {
            methods: owners(s),
            ..base(
                "ideal",
                format!("own sky ({})", s.name()),
                SkyKind::Model(s),
            )
        });
    }
    for m in PolarizationModel::ALL
        .into_iter()
        .map(SkyKind::Model)
        .chain([SkyKind::Field])
    {
        v.push(Scenario {
            methods: all.clone(),
            reference: Some(ref_ideal),
            ..base("sky model", m.label(), m)
        });
    }
    for s in own_skies {
        let sky = SkyKind::Model(s);
        for d in Method::ALL {
            v.push(Scenario {
                chain: Chain::Sensor(stages_none(), d),
                methods: owners(s),
                reference: Some(ref_ideal),
                ..base("demosaic", format!("{} ({})", d.name(), s.name()), sky)
            });
        }
        for (source, st) in [
            ("shot/read noise", noise_stages()),
            ("quantisation (12 bit)", adc_stages()),
            ("fixed patterns + polarizers + crosstalk", fixed_stages()),
        ] {
            v.push(Scenario {
                chain: Chain::Sensor(st, Method::Bilinear),
                methods: owners(s),
                reference: Some(ref_mosaic),
                ..base(source, format!("bilinear ({})", s.name()), sky)
            });
        }
        for (source, told) in [
            ("IMU tilt error", Told::ImuError),
            ("lens: calibration error", Told::Calibration),
            ("lens: pinhole transport assumed", Told::PinholeLens),
        ] {
            v.push(Scenario {
                told,
                methods: owners(s),
                reference: Some(ref_ideal),
                ..base(source, format!("own sky ({})", s.name()), sky)
            });
        }
        v.push(Scenario {
            clouds: true,
            chain: Chain::Sensor(noise_stages(), Method::Bilinear),
            methods: owners(s),
            reference: Some(ref_noise),
            ..base(
                "clouds (20 patches)",
                format!("noisy bilinear ({})", s.name()),
                sky,
            )
        });
    }
    let e2e = |detail: String, sky: SkyKind| Scenario {
        chain: Chain::Sensor(Stages::default(), Method::Bilinear),
        told: Told::Both,
        methods: all.clone(),
        ..base("end to end", detail, sky)
    };
    v.push(e2e("field sky".into(), SkyKind::Field));
    v.push(Scenario {
        told: Told::Truth,
        ..e2e("field sky; IMU and lens exact".into(), SkyKind::Field)
    });
    for d in Method::ALL.into_iter().filter(|&d| d != Method::Bilinear) {
        v.push(Scenario {
            chain: Chain::Sensor(Stages::default(), d),
            ..e2e(format!("field sky + {}", d.name()), SkyKind::Field)
        });
    }
    v.push(Scenario {
        clouds: true,
        ..e2e("field sky + clouds".into(), SkyKind::Field)
    });
    for n in CIE_TYPES {
        v.push(Scenario {
            radiance: Radiance::Cie(n),
            ..e2e(format!("field sky + CIE {n}"), SkyKind::Field)
        });
    }
    for m in PolarizationModel::ALL {
        v.push(e2e(format!("{} sky", m.name()), SkyKind::Model(m)));
    }
    v
}

/// One estimate.
#[derive(Clone, Debug)]
pub struct BudgetFrame {
    /// Source of error.
    pub source: String,
    /// Its variant.
    pub detail: String,
    /// Estimator.
    pub method: HeadingMethod,
    /// Sun elevation, degrees.
    pub sun_elevation: f64,
    /// True yaw, degrees.
    pub yaw: f64,
    /// Yaw error of this scenario, degrees (NaN: no estimate).
    pub error: f64,
    /// The error's change from the paired reference (the error itself without one).
    pub contribution: f64,
    /// Model fit only: fitted (Babinet, Brewster) distances, degrees.
    pub fitted: Option<(f64, f64)>,
}

/// One row of the budget: a source × method.
#[derive(Clone, Debug)]
pub struct BudgetRow {
    /// Source of error.
    pub source: String,
    /// Its variant.
    pub detail: String,
    /// Estimator.
    pub method: HeadingMethod,
    /// Frames.
    pub frames: usize,
    /// Frames without an estimate.
    pub no_estimate: usize,
    /// RMS of the contribution, degrees.
    pub rms: f64,
    /// 95th percentile of |contribution|.
    pub p95: f64,
    /// Largest |contribution|.
    pub max: f64,
    /// Mean of the contribution (its bias), degrees.
    pub mean: f64,
}

fn scene(
    sc: &Scenario,
    intr: Intrinsics,
    stages: Stages,
    exposure: Exposure,
) -> Result<SceneConfig> {
    let mut cfg = SceneConfig::default();
    cfg.camera.intrinsics = intr;
    cfg.sun.zenith_deg = Some(50.0);
    cfg.sun.azimuth_deg = Some(SUN_AZIMUTH);
    cfg.sky = SkyParams {
        radiance: sc.radiance,
        ..sc.sky.params()
    };
    let mut s = SensorConfig::preset(cfg.raw.preset);
    s.exposure = exposure;
    s.stages = stages;
    cfg.raw.sensor = Some(s);
    cfg.raw.sun_disc = Some(false);
    if sc.clouds {
        cfg.raw.soft_clouds = Some(SoftClouds {
            count: 20,
            ..SoftClouds::default()
        });
    }
    Ok(cfg)
}

/// The AoLP/DoLP/S0 images of one frame of `sc`.
fn images(
    sc: &Scenario,
    intr: Intrinsics,
    sun: SunPosition,
    att: &Attitude,
    frame_index: u64,
) -> Result<PolarImages> {
    let stages = match sc.chain {
        Chain::Ideal => Stages::none(),
        Chain::Sensor(s, _) => s,
    };
    let cfg = scene(sc, intr, stages, Exposure::auto())?;
    let pipe = RawPipeline::new(&cfg)?;
    let (st, _) = pipe.stokes(sun, att)?;
    match sc.chain {
        Chain::Ideal => {
            let (dolp, aolp_deg) = psns::stokes::dolp_aolp_images(&st);
            Ok(PolarImages {
                stokes: st,
                dolp,
                aolp_deg,
            })
        }
        Chain::Sensor(s, method) => {
            let frame = pipe
                .render(FrameRequest::planes(frame_index, &st).exact())?
                .frame;
            let layout = pipe.sensor_config().layout;
            if s.quantize {
                let (p, _) = polar_from_codes(
                    &frame.codes,
                    frame.black_level_dn,
                    layout,
                    frame.bit_depth,
                    method,
                )?;
                Ok(p)
            } else {
                let a = frame
                    .analog
                    .as_ref()
                    .ok_or_else(|| Error::Invalid("the sensor kept no unrounded values".into()))?;
                let black = frame.black_level_dn as f32;
                let raw = Image::from_vec(
                    a.width,
                    a.height,
                    a.data.iter().map(|v| v - black).collect(),
                );
                full_chain(&raw, layout, method)
            }
        }
    }
}

/// The setup the estimator is given for a frame with the true tilt [`TILT`].
fn setup(
    told: Told,
    intr: Intrinsics,
    sun: SunPosition,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> HeadingSetup {
    let mut i = intr;
    let calib = |i: &mut Intrinsics| {
        i.focal_length_mm *= 1.0 + FOCAL_ERROR;
        let d = PRINCIPAL_POINT_ERROR_PX * 3.45 / i.pixel_pitch_um;
        i.principal_point = Some([
            0.5 * (i.width as f64 - 1.0) + d,
            0.5 * (i.height as f64 - 1.0) + d,
        ]);
    };
    let n = Normal::new(0.0, IMU_SIGMA_DEG).expect("a valid normal");
    let (mut dp, mut dr) = (0.0, 0.0);
    match told {
        Told::Truth => {}
        Told::ImuError => (dp, dr) = (n.sample(rng), n.sample(rng)),
        Told::Calibration => calib(&mut i),
        Told::PinholeLens => i.lens = Some(Lens::Pinhole),
        Told::Both => {
            (dp, dr) = (n.sample(rng), n.sample(rng));
            calib(&mut i);
        }
    }
    let mut s = HeadingSetup::new(i, sun);
    s.pitch_deg = TILT.0 + dp;
    s.roll_deg = TILT.1 + dr;
    s
}

/// Runs the budget; `progress` sees each finished scenario.
pub fn run_budget(
    opts: &BudgetOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<BudgetFrame>, Vec<BudgetRow>)> {
    let (w, h, k, elevations, yaws): (usize, usize, f64, Vec<f64>, Vec<f64>) = if opts.quick {
        (304, 256, 8.0, vec![35.0], vec![17.0, 197.0])
    } else {
        (
            612,
            512,
            4.0,
            vec![15.0, 35.0, 55.0],
            (0..4).map(|j| 17.0 + 90.0 * j as f64).collect(),
        )
    };
    let intr = Intrinsics {
        pixel_pitch_um: 3.45 * k,
        lens: Some(Lens::Ideal),
        ..Intrinsics::with_size(w, h)
    };
    let mut frames: Vec<BudgetFrame> = Vec::new();
    // (scenario key, method, frame number) → error
    let mut errors: HashMap<(String, HeadingMethod, usize), f64> = HashMap::new();
    for sc in scenarios() {
        // the same IMU draws for every scenario that uses them (seeded per frame)
        for (fi, (&e, &yaw)) in elevations
            .iter()
            .flat_map(|e| yaws.iter().map(move |y| (e, y)))
            .enumerate()
        {
            let sun = SunPosition::new(90.0 - e, SUN_AZIMUTH);
            let att = Attitude::enu(yaw, TILT.0, TILT.1);
            let p = images(&sc, intr, sun, &att, fi as u64)?;
            let view = PolarView {
                aolp_deg: &p.aolp_deg,
                dolp: &p.dolp,
                s0: Some(&p.stokes.s0),
                mask: None,
            };
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x696d_7500 + fi as u64);
            let st = setup(sc.told, intr, sun, &mut rng);
            for &m in &sc.methods {
                let (error, fitted) = match estimate_heading_info(m, &view, &st) {
                    Ok((est, info)) => (
                        wrap180(est.yaw_deg - yaw),
                        info.map(|i| (i.babinet_deg, i.brewster_deg)),
                    ),
                    Err(Error::TooFewPixels(_) | Error::Undetermined(_)) => (f64::NAN, None),
                    Err(e) => return Err(e),
                };
                let contribution = match sc.reference {
                    None => error,
                    Some(r) => {
                        let base = errors.get(&(r(m), m, fi)).copied().ok_or_else(|| {
                            Error::Invalid(format!("budget: no reference {} for {m}", r(m)))
                        })?;
                        wrap180(error - base)
                    }
                };
                errors.insert((sc.key(), m, fi), error);
                frames.push(BudgetFrame {
                    source: sc.source.clone(),
                    detail: sc.detail.clone(),
                    method: m,
                    sun_elevation: e,
                    yaw,
                    error,
                    contribution,
                    fitted,
                });
            }
        }
        progress(&format!("{}: {}", sc.source, sc.detail));
    }
    let mut rows = Vec::new();
    for sc in scenarios() {
        for &m in &sc.methods {
            let c: Vec<f64> = frames
                .iter()
                .filter(|f| f.source == sc.source && f.detail == sc.detail && f.method == m)
                .map(|f| f.contribution)
                .collect();
            let st = error_stats(&c);
            let finite: Vec<f64> = c.iter().copied().filter(|v| v.is_finite()).collect();
            rows.push(BudgetRow {
                source: sc.source.clone(),
                detail: sc.detail.clone(),
                method: m,
                frames: c.len(),
                no_estimate: c.len() - st.count,
                rms: st.rms,
                p95: st.p95,
                max: st.max,
                mean: finite.iter().sum::<f64>() / finite.len().max(1) as f64,
            });
        }
    }
    Ok((frames, rows))
}

/// The rows of the summary table and chart: per method, its own sky's version of each source
/// (the demosaic row bilinear), the field sky's mismatch and the end-to-end error on the field
/// sky, with the root-sum-square of the sources.
pub fn summary(rows: &[BudgetRow]) -> Vec<(HeadingMethod, Vec<(String, BudgetRow)>)> {
    let mut out = Vec::new();
    for m in HeadingMethod::ALL {
        let own = own_model(m).name();
        let pick = |source: &str, detail: &str| {
            rows.iter()
                .find(|r| r.method == m && r.source == source && r.detail == detail)
                .cloned()
        };
        let mut v: Vec<(String, BudgetRow)> = Vec::new();
        let items = [
            (
                "estimator itself (own sky; ideal images)",
                "ideal".to_string(),
                format!("own sky ({own})"),
            ),
            (
                "shot/read noise",
                "shot/read noise".to_string(),
                format!("bilinear ({own})"),
            ),
            (
                "quantisation (12 bit)",
                "quantisation (12 bit)".to_string(),
                format!("bilinear ({own})"),
            ),
            (
                "demosaic (bilinear)",
                "demosaic".to_string(),
                format!("bilinear ({own})"),
            ),
            (
                "fixed patterns + polarizers + crosstalk",
                "fixed patterns + polarizers + crosstalk".to_string(),
                format!("bilinear ({own})"),
            ),
            (
                "sky-model mismatch (field sky)",
                "sky model".to_string(),
                SkyKind::Field.label(),
            ),
            (
                "IMU tilt error (0.5 deg)",
                "IMU tilt error".to_string(),
                format!("own sky ({own})"),
            ),
            (
                "lens: calibration (0.5 % / 3 px)",
                "lens: calibration error".to_string(),
                format!("own sky ({own})"),
            ),
            (
                "lens: pinhole transport assumed",
                "lens: pinhole transport assumed".to_string(),
                format!("own sky ({own})"),
            ),
            (
                "clouds (20 patches)",
                "clouds (20 patches)".to_string(),
                format!("noisy bilinear ({own})"),
            ),
            (
                "end to end (field sky)",
                "end to end".to_string(),
                "field sky".to_string(),
            ),
        ];
        for (label, s, d) in items {
            if let Some(r) = pick(&s, &d) {
                v.push((label.to_string(), r));
            }
        }
        out.push((m, v));
    }
    out
}

/// The chart's name of a summary row.
fn short_label(label: &str) -> &str {
    match label.split(' ').next().unwrap_or("") {
        "estimator" => "estimator",
        "shot/read" => "shot/read noise",
        "quantisation" => "ADC 12 bit",
        "demosaic" => "demosaic",
        "fixed" => "fixed patterns",
        "sky-model" => "sky model",
        "IMU" => "IMU 0.5 deg",
        "lens:" if label.contains("pinhole") => "pinhole lens",
        "lens:" => "calibration",
        "clouds" => "clouds",
        "end" => "end to end",
        _ => label,
    }
}

type PlotErr<E> = plotters::drawing::DrawingAreaErrorKind<E>;
fn perr<E: std::error::Error + Send + Sync>(e: PlotErr<E>) -> Error {
    Error::Invalid(format!("plotting: {e}"))
}

/// The budget chart: per source (x), each method's RMS (bar) and worst frame (cross), log
/// scale.
pub fn budget_svg(rows: &[BudgetRow]) -> Result<String> {
    use plotters::prelude::*;
    let sum = summary(rows);
    let labels: Vec<String> = sum
        .first()
        .map(|(_, v)| v.iter().map(|(l, _)| short_label(l).to_string()).collect())
        .unwrap_or_default();
    if labels.is_empty() {
        return Err(Error::Invalid("nothing to chart".into()));
    }
    let n = labels.len();
    let colours = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
    ];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1300, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(perr)?;
        let lab = labels.clone();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "psns bench heading --budget: yaw error per source (bar: RMS, x: worst frame)",
                ("sans-serif", 18),
            )
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), (1e-5f64..30.0).log_scale())
            .map_err(perr)?;
        chart
            .configure_mesh()
            .x_labels(n)
            .x_label_formatter(&move |x| {
                let k = x.round();
                if (x - k).abs() < 0.01 && k >= 0.0 && (k as usize) < lab.len() {
                    lab[k as usize].clone()
                } else {
                    String::new()
                }
            })
            .y_desc("yaw error, deg (log)")
            .disable_x_mesh()
            .max_light_lines(0)
            .bold_line_style(RGBColor(225, 225, 225))
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(perr)?;
        let clamp = |v: f64| {
            if v.is_finite() {
                v.clamp(1.1e-5, 29.0)
            } else {
                29.0
            }
        };
        for (mi, (m, items)) in sum.iter().enumerate() {
            let col = colours[mi % 3];
            let dx = (mi as f64 - 1.0) * 0.26;
            chart
                .draw_series(items.iter().enumerate().map(|(k, (_, r))| {
                    let x = k as f64 + dx;
                    Rectangle::new([(x - 0.12, 1e-5), (x + 0.12, clamp(r.rms))], col.filled())
                }))
                .map_err(perr)?
                .label(format!("{m} (assumes {})", own_model(*m).name()))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], col.filled()));
            chart
                .draw_series(items.iter().enumerate().map(|(k, (_, r))| {
                    Cross::new((k as f64 + dx, clamp(r.max)), 5, col.stroke_width(2))
                }))
                .map_err(perr)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.9))
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(perr)?;
        root.present().map_err(perr)?;
    }
    Ok(svg)
}

/// `psns bench heading --budget`; returns the files written.
pub fn bench_budget(opts: &BudgetOptions) -> Result<Vec<String>> {
    let mut files = BenchFiles::create(opts.quick, &opts.out)?;
    let t0 = std::time::Instant::now();
    let (frames, rows) = run_budget(opts, &mut |s| {
        eprintln!(
            "psns bench heading --budget: {s} ({:.0} s)",
            t0.elapsed().as_secs_f64()
        )
    })?;
    let mut c = String::from(
        "source,detail,method,assumes,frames,no_estimate,rms_deg,p95_deg,max_deg,mean_deg\n",
    );
    for r in &rows {
        c += &format!(
            "{},{},{},{},{},{},{:.5},{:.5},{:.5},{:.5}\n",
            csv_field(&r.source),
            csv_field(&r.detail),
            r.method,
            own_model(r.method).name(),
            r.frames,
            r.no_estimate,
            r.rms,
            r.p95,
            r.max,
            r.mean
        );
    }
    files.put("budget.csv", &c)?;
    let mut s = String::from("method,source,rms_deg,p95_deg,max_deg\n");
    for (m, items) in summary(&rows) {
        let mut rss = 0.0;
        for (label, r) in &items {
            s += &format!(
                "{m},{},{:.5},{:.5},{:.5}\n",
                csv_field(label),
                r.rms,
                r.p95,
                r.max
            );
            // the sources the end-to-end chain has (not the pinhole transport, not clouds)
            if !label.starts_with("end to end")
                && !label.starts_with("lens: pinhole")
                && !label.starts_with("clouds")
            {
                rss += r.rms * r.rms;
            }
        }
        s += &format!(
            "{m},root-sum-square of the sources in the end-to-end chain,{:.5},,\n",
            rss.sqrt()
        );
    }
    files.put("budget_summary.csv", &s)?;
    let mut f = String::from(
        "source,detail,method,sun_elevation_deg,yaw_deg,error_deg,contribution_deg,fit_babinet_deg,fit_brewster_deg\n",
    );
    for r in &frames {
        let (b, w) = r
            .fitted
            .map(|(b, w)| (format!("{b:.3}"), format!("{w:.3}")))
            .unwrap_or_default();
        f += &format!(
            "{},{},{},{},{},{:.5},{:.5},{b},{w}\n",
            csv_field(&r.source),
            csv_field(&r.detail),
            r.method,
            r.sun_elevation,
            r.yaw,
            r.error,
            r.contribution
        );
    }
    files.put("budget_frames.csv", &f)?;
    // the model fit on Pan's sky: does it find Pan's distances?
    let mut pf = String::from(
        "sky,sun_elevation_deg,frames,pan_babinet_deg,pan_brewster_deg,fit_babinet_deg,fit_brewster_deg,rms_error_deg\n",
    );
    for sky in ["pan", "queen"] {
        let mut es: Vec<f64> = frames.iter().map(|r| r.sun_elevation).collect();
        es.sort_by(f64::total_cmp);
        es.dedup();
        for e in es {
            let fr: Vec<&BudgetFrame> = frames
                .iter()
                .filter(|r| {
                    r.source == "sky model"
                        && r.detail == sky
                        && r.method == HeadingMethod::ModelFit
                        && r.sun_elevation == e
                })
                .collect();
            let fits: Vec<(f64, f64)> = fr.iter().filter_map(|r| r.fitted).collect();
            if fits.is_empty() {
                continue;
            }
            let n = fits.len() as f64;
            let (b, w) = fits.iter().fold((0.0, 0.0), |a, f| (a.0 + f.0, a.1 + f.1));
            let errs: Vec<f64> = fr.iter().map(|r| r.error).collect();
            pf += &format!(
                "{sky},{e},{},{:.3},{:.3},{:.3},{:.3},{:.5}\n",
                fr.len(),
                psns::sky::pan::babinet_deg(e),
                psns::sky::pan::brewster_deg(e),
                b / n,
                w / n,
                error_stats(&errs).rms
            );
        }
    }
    files.put("budget_panfit.csv", &pf)?;
    files.put("budget.svg", &budget_svg(&rows)?)?;
    Ok(files.into_written())
}
