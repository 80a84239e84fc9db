//! `psns bench heading --budget --quick`: every source, sky model and end-to-end variant gets a
//! row for every estimator, with sane values; the sources that must vanish do, the known
//! mismatches do not, and the model fit finds Pan's neutral-point distances on Pan's sky.

use crate::common;

fn read(path: &std::path::Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

fn num(s: &str) -> f64 {
    s.parse()
        .unwrap_or_else(|_| panic!("'{s}' is not a number"))
}

#[test]
fn budget_quick_writes_every_row_with_sane_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b");
    let o = common::psns(&[
        "bench",
        "heading",
        "--budget",
        "--quick",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let rows = read(&out.join("budget.csv"));
    let methods = ["eigen", "model-fit", "hough"];
    let has = |source: &str, detail: &str, m: &str| {
        rows.iter()
            .find(|r| r[0] == source && r[1] == detail && r[2] == m)
            .cloned()
    };
    let models = [
        "wang",
        "rayleigh",
        "depolarized-rayleigh",
        "berry",
        "pan",
        "queen",
        "asymmetric",
    ];
    for m in methods {
        for sky in models
            .iter()
            .copied()
            .chain(["field (asymmetric; Pan; DOP 0.8)"])
        {
            assert!(has("sky model", sky, m).is_some(), "sky model {sky} / {m}");
        }
        for sky in models {
            assert!(
                has("end to end", &format!("{sky} sky"), m).is_some(),
                "{sky} / {m}"
            );
        }
        for d in [
            "field sky",
            "field sky; IMU and lens exact",
            "field sky + clouds",
            "field sky + CIE 1",
            "field sky + CIE 7",
            "field sky + CIE 12",
            "field sky + CIE 15",
            "field sky + superpixel",
            "field sky + eari",
        ] {
            assert!(has("end to end", d, m).is_some(), "end to end {d} / {m}");
        }
    }
    // columns: source,detail,method,assumes,frames,no_estimate,rms,p95,max,mean
    for r in &rows {
        assert_eq!(r.len(), 10, "{r:?}");
        assert_eq!(num(&r[4]), 2.0, "{r:?}");
        assert_eq!(num(&r[5]), 0.0, "a frame without an estimate: {r:?}");
        let (rms, p95, max) = (num(&r[6]), num(&r[7]), num(&r[8]));
        assert!(
            rms.is_finite() && p95.is_finite() && max.is_finite(),
            "{r:?}"
        );
        assert!(
            rms >= 0.0 && p95 <= max + 1e-9 && rms <= max + 1e-9,
            "{r:?}"
        );
        assert!(max < 10.0, "{r:?}");
    }
    // each method on its own sky, ideal images: exact but for Hough's histogram (0.25° bins,
    // a vote band 3° wide), whose own residual is a few hundredths of a degree
    for (m, own, tol) in [
        ("eigen", "rayleigh", 1e-3),
        ("hough", "rayleigh", 0.2),
        ("model-fit", "berry", 1e-3),
    ] {
        let r = has("ideal", &format!("own sky ({own})"), m).unwrap();
        assert!(num(&r[8]) < tol, "{r:?}");
    }
    // the eigenvector method's bias on Berry's field, absent on the depolarized Rayleigh sky
    assert!(num(&has("sky model", "berry", "eigen").unwrap()[6]) > 0.05);
    assert!(num(&has("sky model", "depolarized-rayleigh", "eigen").unwrap()[8]) < 1e-3);
    // the model fit absorbs Pan's and QuEEN's neutral points, not the asymmetric ones
    for sky in ["pan", "queen"] {
        assert!(
            num(&has("sky model", sky, "model-fit").unwrap()[8]) < 0.01,
            "{sky}"
        );
    }
    assert!(num(&has("sky model", "asymmetric", "model-fit").unwrap()[6]) > 0.01);
    // end to end the model fit stays within the 0.2-0.4 deg of published outdoor compasses
    assert!(num(&has("end to end", "field sky", "model-fit").unwrap()[6]) < 0.5);
    let fit = read(&out.join("budget_panfit.csv"));
    assert!(!fit.is_empty());
    for r in &fit {
        // sky,e,frames,pan_babinet,pan_brewster,fit_babinet,fit_brewster,rms
        assert!((num(&r[3]) - num(&r[5])).abs() < 0.05, "{r:?}");
        assert!((num(&r[4]) - num(&r[6])).abs() < 0.05, "{r:?}");
    }
    let summary = std::fs::read_to_string(out.join("budget_summary.csv")).unwrap();
    for m in methods {
        for s in [
            "estimator itself (own sky; ideal images)",
            "shot/read noise",
            "quantisation (12 bit)",
            "demosaic (bilinear)",
            "sky-model mismatch (field sky)",
            "IMU tilt error (0.5 deg)",
            "lens: calibration (0.5 % / 3 px)",
            "end to end (field sky)",
        ] {
            assert!(summary.contains(&format!("{m},{s},")), "{m} {s}");
        }
    }
    assert!(out.join("budget.svg").metadata().unwrap().len() > 2000);
    assert!(out.join("budget_frames.csv").metadata().unwrap().len() > 1000);
    let o = common::psns(&[
        "bench",
        "heading",
        "--budget",
        "--quick",
        "--out",
        "docs/bench",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", common::stderr(&o));
}
