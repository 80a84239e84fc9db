//! `psns._psns`: the psns emulator for Python, a third front-end beside the `psns` binary and the
//! benchmarks. Every formula stays in the `psns` library; this file converts between Python and
//! Rust and nothing else.
//!
//! Keyword arguments are the CLI's long options with underscores (`sun_zenith=50` is
//! `--sun-zenith 50`). They are parsed by the library's option structs ([`psns::options`]), the
//! binary's too, so both front-ends accept the same values and refuse the rest with the same
//! message; the Python package raises it as `ValueError`.
//!
//! Arrays come back as numpy arrays that take over the Rust buffer (no copy); inputs are read in
//! place when they are C-contiguous of the right dtype. Long calls release the GIL.

use clap::{ArgAction, Args, Command, FromArgMatches, Subcommand};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use psns::image::Image;
use pyo3::exceptions::{
    PyFileNotFoundError, PyIsADirectoryError, PyOSError, PyPermissionError, PyRuntimeError,
    PyStopIteration, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------------
// errors

/// The library's error as the Python exception for it: an input file that is missing, not
/// permitted or a directory is `FileNotFoundError`, `PermissionError` or `IsADirectoryError`;
/// other bad input is `ValueError` (exit code 2 in the CLI), I/O is `OSError`, the rest
/// `RuntimeError`; the message is the CLI's.
fn lib_err(e: psns::Error) -> PyErr {
    if let psns::Error::Input { source, .. } = &e {
        use std::io::ErrorKind as K;
        match source.kind() {
            K::NotFound => return PyFileNotFoundError::new_err(e.to_string()),
            K::PermissionDenied => return PyPermissionError::new_err(e.to_string()),
            K::IsADirectory => return PyIsADirectoryError::new_err(e.to_string()),
            _ => {}
        }
    }
    if e.is_usage() {
        PyValueError::new_err(e.to_string())
    } else if matches!(e, psns::Error::Io { .. }) {
        PyOSError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

/// clap's message without the "error: " prefix and the usage lines: the first line of what the
/// CLI prints for the same option, naming keyword arguments (`width=`) where the CLI names its
/// options (`'--width <PX>'`).
fn clap_err(e: clap::Error) -> PyErr {
    let text = e.render().to_string();
    let line = text.lines().next().unwrap_or("bad arguments").trim();
    PyValueError::new_err(keyword_names(line.strip_prefix("error: ").unwrap_or(line)))
}

/// A message with each quoted option (`'--sun-zenith <DEG>'`, `'--clouds'`) written as the
/// keyword argument it is in Python (`sun_zenith=`).
fn keyword_names(msg: &str) -> String {
    let mut out = String::with_capacity(msg.len());
    let mut rest = msg;
    while let Some(i) = rest.find("'--") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 3..];
        let Some(j) = after.find('\'') else {
            out.push_str(&rest[i..]);
            rest = "";
            break;
        };
        let name = after[..j].split([' ', '=']).next().unwrap_or_default();
        out.push_str(&name.replace('-', "_"));
        out.push('=');
        rest = &after[j + 1..];
    }
    out.push_str(rest);
    out
}

// ---------------------------------------------------------------------------------------------
// progress

/// The library's progress as plain lines on stderr, by the rules the CLI uses in a log
/// ([`psns::progress::Schedule`]); `PSNS_PROGRESS=off` silences them.
struct PlainLines;

struct PlainProgress {
    prefix: String,
    unit: psns::progress::Unit,
    total: Option<u64>,
    done: u64,
    msg: String,
    schedule: Option<psns::progress::Schedule>,
    start: std::time::Instant,
}

impl psns::progress::Reporter for PlainLines {
    fn start(
        &self,
        prefix: &str,
        unit: psns::progress::Unit,
        total: Option<u64>,
        long: bool,
    ) -> Box<dyn psns::progress::Progress> {
        use psns::progress::{mode, period, Mode, Schedule, DEFAULT_PERIOD, ENV_MODE, ENV_PERIOD};
        let off = mode(false, std::env::var(ENV_MODE).ok().as_deref()) == Mode::Off;
        let p = period(std::env::var(ENV_PERIOD).ok().as_deref()).unwrap_or(DEFAULT_PERIOD);
        Box::new(PlainProgress {
            prefix: prefix.to_string(),
            unit,
            total,
            done: 0,
            msg: String::new(),
            schedule: (!off).then(|| Schedule::new(p, long)),
            start: std::time::Instant::now(),
        })
    }
}

impl psns::progress::Progress for PlainProgress {
    fn set_message(&mut self, msg: &str) {
        self.msg = msg.to_string();
    }
    fn inc(&mut self, n: u64) {
        self.done += n;
        let elapsed = self.start.elapsed();
        if let Some(s) = &mut self.schedule {
            if s.due(elapsed, self.done, self.total) {
                let line = psns::progress::plain_line(
                    &self.prefix,
                    self.unit,
                    self.done,
                    self.total,
                    elapsed,
                    &self.msg,
                );
                eprintln!("{line}");
            }
        }
    }
    fn println(&mut self, line: &str) {
        eprintln!("{line}");
    }
}

// ---------------------------------------------------------------------------------------------
// keyword arguments -> the CLI's options

/// One option value as the CLI would read it.
fn value_text(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(l) = v.cast::<PyList>() {
        return join(l.iter());
    }
    if let Ok(t) = v.cast::<PyTuple>() {
        return join(t.iter());
    }
    Ok(v.str()?.to_string())
}

fn join<'py>(items: impl Iterator<Item = Bound<'py, PyAny>>) -> PyResult<String> {
    let parts: PyResult<Vec<String>> = items.map(|x| Ok(x.str()?.to_string())).collect();
    Ok(parts?.join(","))
}

/// The command line of `kwargs` for `cmd`: `name=value` becomes `--name=value`, a flag given a
/// true value `--name`, a list `a,b,c`, `sensor_set={"prnu": 0.01}` one `--sensor-set` per key;
/// `None` and false flags are left out. Unknown names pass through, so clap refuses them with the
/// CLI's message.
fn argv(cmd: &Command, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    let Some(kw) = kwargs else { return Ok(out) };
    for (k, v) in kw.iter() {
        let key: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        let long = key.replace('_', "-");
        let arg = cmd
            .get_arguments()
            .find(|a| a.get_long() == Some(long.as_str()));
        let flag = arg.is_some_and(|a| matches!(a.get_action(), ArgAction::SetTrue));
        let repeated = arg.is_some_and(|a| matches!(a.get_action(), ArgAction::Append));
        if flag {
            if v.is_truthy()? {
                out.push(format!("--{long}"));
            }
        } else if let (true, Ok(d)) = (repeated, v.cast::<PyDict>()) {
            // --sensor-set KEY=JSON per entry
            let json = PyModule::import(v.py(), "json")?;
            for (dk, dv) in d.iter() {
                let val: String = json.call_method1("dumps", (dv,))?.extract()?;
                out.push(format!("--{long}={}={val}", dk.str()?));
            }
        } else if let (true, Ok(l)) = (repeated, v.cast::<PyList>()) {
            for x in l.iter() {
                out.push(format!("--{long}={}", x.str()?));
            }
        } else {
            out.push(format!("--{long}={}", value_text(&v)?));
        }
    }
    Ok(out)
}

/// Parses keyword arguments (and leading positional words) into the option struct `A`.
fn parse<A: Args + FromArgMatches>(
    name: &'static str,
    positional: &[&str],
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<A> {
    let cmd = psns::options::negative_numbers(A::augment_args(Command::new(name)));
    let mut words = vec![name.to_string()];
    words.extend(positional.iter().map(|s| s.to_string()));
    words.extend(argv(&cmd, kwargs)?);
    let m = cmd.try_get_matches_from(words).map_err(clap_err)?;
    A::from_arg_matches(&m).map_err(clap_err)
}

/// A scene (and sensor) from `psns render` options; `raw` adds `--raw`.
fn render_args(
    kwargs: Option<&Bound<'_, PyDict>>,
    raw: bool,
) -> PyResult<psns::options::RenderArgs> {
    let flag: &[&str] = if raw { &["--raw"] } else { &[] };
    parse::<psns::options::RenderArgs>("render", flag, kwargs)
}

// ---------------------------------------------------------------------------------------------
// arrays

fn array2<'py, T: numpy::Element>(py: Python<'py>, img: Image<T>) -> Bound<'py, PyAny> {
    let (w, h) = (img.width, img.height);
    Array2::from_shape_vec((h, w), img.data)
        .expect("image size matches its data")
        .into_pyarray(py)
        .into_any()
}

/// ADC codes as the CLI writes them to raw.png: uint8 at 8 bits, else uint16.
fn codes_array<'py>(py: Python<'py>, codes: Image<u16>, bit_depth: u8) -> Bound<'py, PyAny> {
    if bit_depth <= 8 {
        let (w, h) = (codes.width, codes.height);
        let b: Vec<u8> = codes.data.iter().map(|&v| v as u8).collect();
        array2(py, Image::from_vec(w, h, b))
    } else {
        array2(py, codes)
    }
}

/// A 2-D uint8 or uint16 array as 16-bit codes and its significant bits (8 for uint8).
fn codes_in(raw: &Bound<'_, PyAny>) -> PyResult<(Image<u16>, u8)> {
    if let Ok(a) = raw.cast::<numpy::PyArray2<u16>>() {
        let r = a.readonly();
        let (h, w) = (r.shape()[0], r.shape()[1]);
        let data = match r.as_slice() {
            Ok(s) => s.to_vec(),
            Err(_) => r.as_array().iter().copied().collect(),
        };
        return Ok((Image::from_vec(w, h, data), 16));
    }
    if let Ok(a) = raw.cast::<numpy::PyArray2<u8>>() {
        let r = a.readonly();
        let (h, w) = (r.shape()[0], r.shape()[1]);
        let data = r.as_array().iter().map(|&v| v as u16).collect();
        return Ok((Image::from_vec(w, h, data), 8));
    }
    Err(PyValueError::new_err(
        "raw must be a 2-D numpy array of uint16 or uint8 ADC codes (rows x columns)",
    ))
}

// ---------------------------------------------------------------------------------------------
// functions

/// Ideal images of a scene, like `psns render`: float32 arrays `li`, `dop`, `aop` (degrees)
/// and the uint8 class image `class` (`docs/world.md`).
#[pyfunction]
#[pyo3(signature = (**scene))]
fn render<'py>(
    py: Python<'py>,
    scene: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = render_args(scene, false)?;
    let r = py.detach(|| -> psns::Result<_> {
        let (cfg, _) = a.config()?;
        let (sky, cam) = cfg.build()?;
        let class = psns::render::class_image(&sky, &cam, cfg.raw.sun_disc_on());
        Ok((psns::render::render_ideal(&sky, &cam), class))
    });
    let (ideal, class) = r.map_err(lib_err)?;
    let d = PyDict::new(py);
    d.set_item("li", array2(py, ideal.li))?;
    d.set_item("dop", array2(py, ideal.dop))?;
    d.set_item("aop", array2(py, ideal.aop_deg))?;
    d.set_item("class", array2(py, class))?;
    Ok(d)
}

/// The raw frame of `psns render --raw` and its ground truth.
#[pyfunction]
#[pyo3(signature = (**scene_and_sensor))]
fn render_raw<'py>(
    py: Python<'py>,
    scene_and_sensor: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = render_args(scene_and_sensor, true)?;
    let frame = py.detach(|| -> psns::Result<_> {
        let (cfg, _) = a.config()?;
        let pipe = psns::pipeline::RawPipeline::new(&cfg)?;
        let r = pipe.render(pipe.configured_request()?)?;
        let dolp_aolp = r.frame.truth_dolp_aolp();
        Ok((r.frame, r.record, dolp_aolp))
    });
    let (frame, record, (dolp, aolp)) = frame.map_err(lib_err)?;
    let d = PyDict::new(py);
    let meta = record_dict(py, &record)?;
    let psns::sensor::RawFrame {
        codes,
        bit_depth,
        truth,
        ..
    } = frame;
    d.set_item("raw", codes_array(py, codes, bit_depth))?;
    d.set_item("truth_s0", array2(py, truth.s0))?;
    d.set_item("truth_s1", array2(py, truth.s1))?;
    d.set_item("truth_s2", array2(py, truth.s2))?;
    d.set_item("truth_dolp", array2(py, dolp))?;
    d.set_item("truth_aolp", array2(py, aolp))?;
    d.set_item("meta", meta)?;
    Ok(d)
}

/// A frame's record as a dict: its fields by name (`None` where a value is absent).
fn record_dict<'py>(
    py: Python<'py>,
    rec: &psns::record::FrameRecord,
) -> PyResult<Bound<'py, PyDict>> {
    json_dict(
        py,
        &serde_json::to_value(rec).expect("a frame record serializes"),
    )
}

/// A JSON object as a dict.
fn json_dict<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyDict>> {
    let json = PyModule::import(py, "json")?;
    Ok(json
        .call_method1("loads", (v.to_string(),))?
        .cast_into::<PyDict>()?)
}

/// S0, S1, S2, DoLP, AoLP of a raw mosaic, like `psns demosaic`.
#[pyfunction]
#[pyo3(signature = (raw, method = "bilinear", black_level = 0.0, **opts))]
fn demosaic<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    method: &str,
    black_level: f64,
    opts: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let m = format!("--method={method}");
    let a = parse::<psns::options::DemosaicArgs>("demosaic", &["<array>", &m], opts)?;
    if a.frame.is_some() {
        return Err(PyValueError::new_err(
            "--frame applies to stream input only",
        ));
    }
    let (codes, _) = codes_in(raw)?;
    let black =
        psns::error::check_range("black_level", black_level, 0.0, 65535.0).map_err(lib_err)?;
    let out = py.detach(|| -> psns::Result<_> {
        if let Some(sigma) = a.dolp_debias {
            psns::error::check_range("dolp-debias", sigma, 0.0, 1e6)?;
        }
        psns::demosaic::check_raw(&codes)?;
        let p = psns::demosaic::demosaic_codes(&codes, black, a.layout, a.method)?;
        let deb = a
            .dolp_debias
            .map(|s| psns::stokes::debiased_dolp_image(&p.stokes, s as f32));
        Ok((p, deb))
    });
    let (p, deb) = out.map_err(lib_err)?;
    let d = PyDict::new(py);
    d.set_item("s0", array2(py, p.stokes.s0))?;
    d.set_item("s1", array2(py, p.stokes.s1))?;
    d.set_item("s2", array2(py, p.stokes.s2))?;
    d.set_item("dolp", array2(py, p.dolp))?;
    d.set_item("aolp", array2(py, p.aolp_deg))?;
    if let Some(x) = deb {
        d.set_item("dolp_debiased", array2(py, x))?;
    }
    Ok(d)
}

/// The camera's yaw from one raw mosaic, like `psns heading IMAGE`.
#[pyfunction]
#[pyo3(signature = (raw, **sun_and_tilt))]
fn heading<'py>(
    py: Python<'py>,
    raw: &Bound<'py, PyAny>,
    sun_and_tilt: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = parse::<psns::options::HeadingArgs>("heading", &["<array>"], sun_and_tilt)?;
    if a.index.is_some() {
        // the CLI's image path refuses it while reading the file, which an array skips
        return Err(PyValueError::new_err(
            "--index applies to stream input only",
        ));
    }
    a.check_image_options().map_err(lib_err)?;
    let (codes, bits) = codes_in(raw)?;
    let loaded = psns::io::LoadedRaw {
        codes,
        layout: Default::default(),
        black_level: 0.0,
        bits,
        frame: None,
    };
    let r = py.detach(|| -> psns::Result<_> {
        // an array has no scene.json beside it: the sun comes from the keyword arguments
        let (setup, _) = a.image_setup(None)?;
        let r = a.estimate_image(&setup, &loaded, "the array")?;
        Ok((r, setup.sun.azimuth_deg))
    });
    let (r, sun_azimuth) = r.map_err(lib_err)?;
    if let Some(m) = &r.reason {
        eprintln!("psns: {m}");
    }
    let saturated = r.saturated;
    let d = PyDict::new(py);
    match r.estimate {
        Some(e) => {
            d.set_item("yaw_deg", a.reported_yaw(e.yaw_deg, sun_azimuth))?;
            d.set_item("confidence", e.confidence)?;
            d.set_item("pixels", e.pixels)?;
            d.set_item("residual_deg", e.residual_deg)?;
            d.set_item("sky_fraction", e.sky_fraction)?;
        }
        None => {
            d.set_item("yaw_deg", f64::NAN)?;
            d.set_item("confidence", 0.0)?;
            d.set_item("pixels", 0)?;
            d.set_item("residual_deg", f64::NAN)?;
            d.set_item("sky_fraction", 0.0)?;
        }
    }
    d.set_item("saturated_pixels", saturated)?;
    Ok(d)
}

/// Sky values for directions, like `psns sky`, vectorised over numpy arrays.
#[pyfunction]
#[pyo3(signature = (zenith, azimuth, **sky))]
fn sky<'py>(
    py: Python<'py>,
    zenith: &Bound<'py, PyAny>,
    azimuth: &Bound<'py, PyAny>,
    sky: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = parse::<psns::options::SkyArgs>("sky", &[], sky)?;
    if a.stability {
        return Err(PyValueError::new_err(
            "--stability writes files: run `psns sky --stability` instead",
        ));
    }
    let np = PyModule::import(py, "numpy")?;
    let bc = np.call_method1("broadcast_arrays", (zenith, azimuth))?;
    let as_f64 = |x: Bound<'py, PyAny>| -> PyResult<Bound<'py, PyAny>> {
        let kw = PyDict::new(py);
        kw.set_item("dtype", "float64")?;
        np.call_method("ascontiguousarray", (x,), Some(&kw))
    };
    let z = as_f64(bc.get_item(0)?)?;
    let az = as_f64(bc.get_item(1)?)?;
    let shape = z.getattr("shape")?;
    let zv: Vec<f64> = z.call_method0("ravel")?.extract()?;
    let av: Vec<f64> = az.call_method0("ravel")?.extract()?;
    if let Some(bad) = zv.iter().find(|v| !(0.0..=180.0).contains(*v)) {
        return Err(lib_err(psns::Error::range("zenith", *bad, "0..180")));
    }
    if let Some(bad) = av.iter().find(|v| !v.is_finite()) {
        return Err(lib_err(psns::Error::range(
            "azimuth",
            *bad,
            "a finite number",
        )));
    }
    let cols = py.detach(|| -> psns::Result<_> {
        use rayon::prelude::*;
        let cfg = a.scene.scene()?;
        let sun = cfg.sun.resolve()?;
        let s = psns::sky::Sky::new(sun, &cfg.sky)?;
        let rows: Vec<[f64; 5]> = zv
            .par_iter()
            .zip(av.par_iter())
            .map(|(&z, &a)| {
                let v = s.values(z, a);
                [
                    v.gamma_deg,
                    v.radiance,
                    v.dop,
                    v.aop_meridian_deg,
                    v.aop_north_deg,
                ]
            })
            .collect();
        Ok((0..5)
            .map(|k| rows.iter().map(|r| r[k]).collect::<Vec<f64>>())
            .collect::<Vec<_>>())
    });
    let cols = cols.map_err(lib_err)?;
    let d = PyDict::new(py);
    let names = [
        "gamma_deg",
        "radiance",
        "dop",
        "aop_meridian_deg",
        "aop_north_deg",
    ];
    for (name, c) in names.iter().zip(cols) {
        let arr = PyArray1::from_vec(py, c).call_method1("reshape", (&shape,))?;
        d.set_item(*name, arr)?;
    }
    Ok(d)
}

/// Builds a dataset or one shard of it, like `psns dataset build`.
#[pyfunction]
#[pyo3(signature = (config, out, shard = None, resume = false, jobs = None, dry_run = false))]
fn dataset_build(
    py: Python<'_>,
    config: Option<PathBuf>,
    out: PathBuf,
    shard: Option<(i64, i64)>,
    resume: bool,
    jobs: Option<i64>,
    dry_run: bool,
) -> PyResult<()> {
    let mut words = vec![
        "dataset".to_string(),
        "build".into(),
        format!("--out={}", out.display()),
    ];
    if let Some(c) = config {
        words.push(format!("--config={}", c.display()));
    }
    if let Some((k, n)) = shard {
        words.push(format!("--shard={k}/{n}"));
    }
    if resume {
        words.push("--resume".into());
    }
    if let Some(j) = jobs {
        words.push(format!("--jobs={j}"));
    }
    if dry_run {
        words.push("--dry-run".into());
    }
    let cmd = psns::options::negative_numbers(psns::options::DatasetCmd::augment_subcommands(
        Command::new("dataset"),
    ));
    let m = cmd.try_get_matches_from(words).map_err(clap_err)?;
    let psns::options::DatasetCmd::Build(a) =
        psns::options::DatasetCmd::from_arg_matches(&m).map_err(clap_err)?
    else {
        unreachable!("the words name the build subcommand");
    };
    let summary = py.detach(|| a.run(&PlainLines)).map_err(lib_err)?;
    if let Some(s) = summary {
        eprintln!("{s}");
    }
    Ok(())
}

/// A whole number 0..2^64-1 from Python: a negative or too large int is `ValueError` with the
/// CLI's range message (not `OverflowError`), anything else `TypeError`.
fn index_arg(name: &str, v: &Bound<'_, PyAny>) -> PyResult<u64> {
    if let Ok(u) = v.extract::<u64>() {
        return Ok(u);
    }
    if v.is_instance_of::<pyo3::types::PyInt>() {
        return Err(PyValueError::new_err(format!(
            "{name} = {} is out of range (allowed a whole number 0..18446744073709551615)",
            v.str()?
        )));
    }
    Err(pyo3::exceptions::PyTypeError::new_err(format!(
        "{name} must be a whole number, not {}",
        v.get_type().name()?
    )))
}

// ---------------------------------------------------------------------------------------------
// Camera

/// A camera that keeps its fixed patterns and caches between frames (see the Python docstring).
#[pyclass(module = "psns._psns")]
struct Camera {
    pipe: psns::pipeline::RawPipeline,
    next_index: u64,
}

#[pymethods]
impl Camera {
    #[new]
    #[pyo3(signature = (**scene_and_sensor))]
    fn new(py: Python<'_>, scene_and_sensor: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let a = render_args(scene_and_sensor, true)?;
        let pipe = py.detach(|| -> psns::Result<_> {
            let (cfg, _) = a.config()?;
            psns::pipeline::RawPipeline::new(&cfg)
        });
        let pipe = pipe.map_err(lib_err)?;
        let next_index = pipe.config().raw.frame_index;
        Ok(Camera { pipe, next_index })
    }

    #[getter]
    fn width(&self) -> usize {
        self.pipe.config().camera.intrinsics.width
    }

    #[getter]
    fn height(&self) -> usize {
        self.pipe.config().camera.intrinsics.height
    }

    #[getter]
    fn bit_depth(&self) -> u8 {
        self.pipe.sensor_config().bit_depth
    }

    /// The scene and sensor configuration, as scene.json records it.
    #[getter]
    fn config(&self) -> String {
        let mut c = self.pipe.config().clone();
        c.raw.sensor = Some(self.pipe.sensor_config().clone());
        c.to_json()
    }

    #[pyo3(signature = (yaw = None, pitch = None, roll = None, sun_zenith = None, sun_azimuth = None, frame_index = None, meta = false))]
    #[allow(clippy::too_many_arguments)]
    fn frame<'py>(
        &mut self,
        py: Python<'py>,
        yaw: Option<f64>,
        pitch: Option<f64>,
        roll: Option<f64>,
        sun_zenith: Option<f64>,
        sun_azimuth: Option<f64>,
        frame_index: Option<Bound<'py, PyAny>>,
        meta: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        use psns::camera::Attitude;
        let frame_index = frame_index
            .map(|v| index_arg("frame_index", &v))
            .transpose()?;
        let cfg = self.pipe.config();
        let (frame, y0, p0, r0) = match cfg.camera.attitude {
            Attitude::Euler {
                frame,
                yaw_deg,
                pitch_deg,
                roll_deg,
            } => (frame, yaw_deg, pitch_deg, roll_deg),
            Attitude::Quaternion { frame, .. } => (frame, 0.0, 0.0, 0.0),
        };
        if let Attitude::Quaternion { .. } = cfg.camera.attitude {
            // as the CLI refuses --yaw with --quaternion: a quaternion has no yaw to replace
            let given = [("yaw", yaw), ("pitch", pitch), ("roll", roll)];
            if let Some((name, _)) = given.iter().find(|(_, v)| v.is_some()) {
                return Err(PyValueError::new_err(format!(
                    "{name}= cannot be used with quaternion=: this camera's attitude is a \
                     quaternion; make a Camera with yaw=, pitch= and roll= to turn it by angles"
                )));
            }
        }
        let attitude = match (cfg.camera.attitude, yaw, pitch, roll) {
            (q @ Attitude::Quaternion { .. }, None, None, None) => q,
            _ => Attitude::Euler {
                frame,
                yaw_deg: yaw.unwrap_or(y0),
                pitch_deg: pitch.unwrap_or(p0),
                roll_deg: roll.unwrap_or(r0),
            },
        };
        for (name, v) in [("yaw", yaw), ("pitch", pitch), ("roll", roll)] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(lib_err(psns::Error::range(name, v, "a finite number")));
            }
        }
        attitude.validate().map_err(lib_err)?;
        let mut sun_cfg = cfg.sun.clone();
        if sun_zenith.is_some() || sun_azimuth.is_some() {
            let now = cfg.sun.resolve().map_err(lib_err)?;
            sun_cfg.time = None;
            sun_cfg.altitude_deg = None;
            sun_cfg.zenith_deg = Some(sun_zenith.unwrap_or(now.zenith_deg));
            sun_cfg.azimuth_deg = Some(sun_azimuth.unwrap_or(now.azimuth_deg));
        }
        let index = frame_index.unwrap_or(self.next_index);
        let pipe = &self.pipe;
        let r = py.detach(|| -> psns::Result<_> {
            let sun = sun_cfg.resolve()?;
            sun_cfg.check_up(sun)?;
            let req = psns::pipeline::FrameRequest::sky(index, sun, attitude);
            pipe.render(req)
        });
        let r = r.map_err(lib_err)?;
        self.next_index = index + 1;
        let arr = codes_array(py, r.frame.codes, r.frame.bit_depth);
        if !meta {
            return Ok(arr);
        }
        let d = record_dict(py, &r.record)?;
        Ok(PyTuple::new(py, [arr, d.into_any()])?.into_any())
    }
}

// ---------------------------------------------------------------------------------------------
// streams

type Source = Box<dyn std::io::Read + Send + Sync>;

/// Iterates over the intact frames of a stream (see the Python docstring of `open_stream`).
#[pyclass(module = "psns._psns")]
struct StreamIter {
    reader: psns::stream::StreamReader<Source>,
    tally: psns::stream::VerifyTally,
    damage: Vec<psns::stream::Damage>,
    /// The abort was reported (a warning once per stream).
    abort_warned: bool,
}

/// Raises `psns.StreamAbortedWarning` (a `StreamDamageWarning`) for a stream its producer
/// marked aborted.
fn warn_aborted(py: Python<'_>, reason: &str) -> PyResult<()> {
    let warnings = PyModule::import(py, "warnings")?;
    let cat = PyModule::import(py, "psns")?.getattr("StreamAbortedWarning")?;
    let msg = format!("stream aborted by its producer: {reason}");
    warnings.call_method1("warn", (msg, cat, 2))?;
    Ok(())
}

#[pyfunction]
fn open_stream(py: Python<'_>, path: PathBuf) -> PyResult<StreamIter> {
    let r = py.detach(|| -> psns::Result<_> {
        psns::stream::StreamReader::new(psns::io::open_input(&path)?)
    });
    let reader = r.map_err(lib_err)?;
    let tally = psns::stream::VerifyTally::new(reader.header().clone(), None);
    Ok(StreamIter {
        reader,
        tally,
        damage: Vec::new(),
        abort_warned: false,
    })
}

fn meta_dict<'py>(
    py: Python<'py>,
    m: &psns::stream::FrameMeta,
    h: &psns::stream::FileHeader,
) -> PyResult<Bound<'py, PyDict>> {
    let d = json_dict(
        py,
        &serde_json::to_value(m).expect("frame metadata serializes"),
    )?;
    d.set_item("last", m.flags & psns::stream::FLAG_LAST != 0)?;
    d.set_item("bits", h.bits_valid)?;
    d.set_item("msb_aligned", h.msb_aligned)?;
    Ok(d)
}

#[pymethods]
impl StreamIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        loop {
            let reader = &mut self.reader;
            let ev = py.detach(|| -> psns::Result<_> {
                let ev = reader.next_event()?;
                // unpack while the GIL is released
                let codes = match &ev {
                    Some(psns::stream::Event::Frame(f)) if f.payload_crc_ok => {
                        Some(f.codes(reader.header())?)
                    }
                    _ => None,
                };
                Ok((ev, codes))
            });
            let (ev, codes) = ev.map_err(lib_err)?;
            let Some(ev) = ev else {
                // a header marked aborted without an end record (it did not fit on a full disk)
                if !self.abort_warned && self.reader.header().aborted {
                    self.abort_warned = true;
                    warn_aborted(py, psns::stream::REASON_NOT_RECORDED)?;
                }
                return Err(PyStopIteration::new_err(()));
            };
            if let psns::stream::Event::Aborted { reason, .. } = &ev {
                self.abort_warned = true;
                warn_aborted(py, reason)?;
            }
            if let Some(d) = self.tally.record(&ev) {
                self.damage.push(d.clone());
                let warnings = PyModule::import(py, "warnings")?;
                let psns_mod = PyModule::import(py, "psns")?;
                let cat = psns_mod.getattr("StreamDamageWarning")?;
                let id = d.index.map_or("?".to_string(), |i| i.to_string());
                let msg = format!("frame {id} at byte {}: {}", d.offset, d.reason);
                warnings.call_method1("warn", (msg, cat, 2))?;
            }
            if let (psns::stream::Event::Frame(f), Some(codes)) = (ev, codes) {
                let h = self.reader.header();
                let img = Image::from_vec(h.width as usize, h.height as usize, codes);
                let meta = meta_dict(py, &f.meta, h)?;
                let arr = array2(py, img);
                return PyTuple::new(
                    py,
                    [
                        f.meta.index.into_pyobject(py)?.into_any(),
                        meta.into_any(),
                        arr,
                    ],
                );
            }
        }
    }

    /// The file header as a dict.
    #[getter]
    fn header<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = serde_json::to_value(self.reader.header()).expect("header serializes");
        PyModule::import(py, "json")?.call_method1("loads", (v.to_string(),))
    }

    /// What `psns verify` would report on the frames read so far, as text.
    fn report(&self) -> String {
        self.tally.finish(self.reader.restart_offsets()).to_string()
    }

    /// The same report as a dict (what `psns verify --json` prints).
    fn report_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let rep = self.tally.finish(self.reader.restart_offsets());
        let v = serde_json::to_string(&rep).expect("report serializes");
        PyModule::import(py, "json")?.call_method1("loads", (v,))
    }

    /// True when nothing was damaged, dropped or skipped so far.
    #[getter]
    fn intact(&self) -> bool {
        self.tally.finish(self.reader.restart_offsets()).intact()
    }

    /// Why the producer aborted the stream (its end record, or the header's mark), if it did.
    #[getter]
    fn aborted(&self) -> Option<String> {
        self.tally.finish(self.reader.restart_offsets()).aborted
    }
}

// ---------------------------------------------------------------------------------------------

#[pymodule]
fn _psns(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(render_raw, m)?)?;
    m.add_function(wrap_pyfunction!(demosaic, m)?)?;
    m.add_function(wrap_pyfunction!(heading, m)?)?;
    m.add_function(wrap_pyfunction!(sky, m)?)?;
    m.add_function(wrap_pyfunction!(dataset_build, m)?)?;
    m.add_function(wrap_pyfunction!(open_stream, m)?)?;
    m.add_class::<Camera>()?;
    m.add_class::<StreamIter>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
