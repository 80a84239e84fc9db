//! The name tables of the library's enums (`psns::names`): every value's name parses back to
//! it through the table, clap and `FromStr`, serde writes the same name, and a bad name's message
//! lists the table.

use clap::ValueEnum;
use psns::camera::{AttitudeFrame, Lens, Projection};
use psns::config::SceneKind;
use psns::demosaic::Method;
use psns::heading::HeadingMethod;
use psns::sensor::packing::PixelFormat;
use psns::sensor::{Preset, Stages};
use psns::sky::{DopModel, DopNorm, PolarizationModel};

/// Each value's name parses back to it (any case), through the table, clap and `FromStr`
/// where the enum has one, and `names()` lists them all in order.
fn round_trip<T>(all: &[T], name: fn(T) -> &'static str, names: String)
where
    T: ValueEnum + Copy + PartialEq + std::fmt::Debug,
{
    assert_eq!(T::value_variants(), all);
    let listed: Vec<&str> = all.iter().map(|&v| name(v)).collect();
    assert_eq!(names, listed.join(", "));
    for &v in all {
        let n = name(v);
        assert_eq!(T::from_str(n, false), Ok(v));
        assert_eq!(T::from_str(&n.to_ascii_uppercase(), true), Ok(v));
        assert!(T::from_str(&format!("{n}x"), true).is_err());
    }
}

/// Serde writes a value by the table's name, so scene files and the command line agree.
fn serde_name<T: serde::Serialize>(v: T, name: &str) {
    assert_eq!(serde_json::to_value(v).unwrap(), name, "serde name");
}

#[test]
fn every_table_round_trips() {
    round_trip(
        &PolarizationModel::ALL,
        PolarizationModel::name,
        PolarizationModel::names(),
    );
    round_trip(&DopNorm::ALL, DopNorm::name, DopNorm::names());
    round_trip(&DopModel::ALL, DopModel::name, DopModel::names());
    round_trip(
        &AttitudeFrame::ALL,
        AttitudeFrame::name,
        AttitudeFrame::names(),
    );
    round_trip(&SceneKind::ALL, SceneKind::name, SceneKind::names());
    round_trip(&Projection::ALL, Projection::name, Projection::names());
    round_trip(&Lens::ALL, Lens::name, Lens::names());
    round_trip(&Preset::ALL, Preset::name, Preset::names());
    round_trip(&PixelFormat::ALL, PixelFormat::name, PixelFormat::names());
    round_trip(&Method::ALL, Method::name, Method::names());
    round_trip(
        &HeadingMethod::ALL,
        HeadingMethod::name,
        HeadingMethod::names(),
    );
    for v in PolarizationModel::ALL {
        serde_name(v, v.name());
        assert_eq!(v.name().parse::<PolarizationModel>().unwrap(), v);
    }
    for v in DopNorm::ALL {
        serde_name(v, v.name());
    }
    for v in DopModel::ALL {
        serde_name(v, v.name());
    }
    for v in AttitudeFrame::ALL {
        serde_name(v, v.name());
    }
    for v in SceneKind::ALL {
        serde_name(v, v.name());
    }
    for v in Projection::ALL {
        serde_name(v, v.name());
        assert_eq!(v.name().parse::<Projection>().unwrap(), v);
    }
    for v in Lens::ALL {
        serde_name(v, v.name());
        assert_eq!(v.name().parse::<Lens>().unwrap(), v);
    }
    for v in Preset::ALL {
        serde_name(v, v.name());
        assert_eq!(v.name().parse::<Preset>().unwrap(), v);
    }
    for v in PixelFormat::ALL {
        // scene files and stream headers keep the PFNC name
        serde_name(v, v.pfnc_name());
        assert_eq!(v.pfnc_name().to_ascii_lowercase(), v.name());
        assert_eq!(v.pfnc_name().parse::<PixelFormat>().unwrap(), v);
    }
    for v in Method::ALL {
        assert_eq!(v.name().parse::<Method>().unwrap(), v);
    }
    for v in HeadingMethod::ALL {
        assert_eq!(v.name().parse::<HeadingMethod>().unwrap(), v);
    }
}

/// A bad name's message lists the table's names.
#[test]
fn messages_list_the_table() {
    let e = |r: String, names: String| assert!(r.ends_with(&format!("{names})")), "{r}");
    e(
        "x".parse::<PolarizationModel>().unwrap_err().to_string(),
        PolarizationModel::names(),
    );
    e(
        "x".parse::<Projection>().unwrap_err().to_string(),
        Projection::names(),
    );
    e("x".parse::<Lens>().unwrap_err().to_string(), Lens::names());
    e(
        "x".parse::<Preset>().unwrap_err().to_string(),
        Preset::names(),
    );
    e(
        "x".parse::<PixelFormat>().unwrap_err().to_string(),
        PixelFormat::names(),
    );
    e(
        "x".parse::<Method>().unwrap_err().to_string(),
        Method::names(),
    );
    e(
        "x".parse::<HeadingMethod>().unwrap_err().to_string(),
        HeadingMethod::names(),
    );
}

/// The stage names are the sensor settings' field names, in order.
#[test]
fn stage_names_are_the_fields() {
    let v = serde_json::to_value(Stages::default()).unwrap();
    let mut fields: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
    let mut names = Stages::NAMES.to_vec();
    fields.sort_unstable();
    names.sort_unstable();
    assert_eq!(fields, names);
}
