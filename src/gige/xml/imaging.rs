//! Features of the image and its acquisition: size, region, pixel format, exposure, gain,
//! black level, acquisition modes, frame rate, triggers.

use super::*;

pub(super) fn image_format(x: &mut X) {
    x.integer(
        "SensorWidth",
        "Columns of the sensor.",
        false,
        false,
        "SensorWidthReg",
        &[],
        Some("px"),
        None,
    );
    x.int_reg("SensorWidthReg", addr::SENSOR_WIDTH, 4, Access::Ro);
    x.integer(
        "SensorHeight",
        "Rows of the sensor.",
        false,
        false,
        "SensorHeightReg",
        &[],
        Some("px"),
        None,
    );
    x.int_reg("SensorHeightReg", addr::SENSOR_HEIGHT, 4, Access::Ro);
    x.integer(
        "WidthMax",
        "Largest width.",
        false,
        false,
        "SensorWidthReg",
        &[],
        Some("px"),
        None,
    );
    x.integer(
        "HeightMax",
        "Largest height.",
        false,
        false,
        "SensorHeightReg",
        &[],
        Some("px"),
        None,
    );
    let two = || ("Min", "2".to_string());
    let inc = || ("Inc", "2".to_string());
    x.integer(
        "Width",
        "Width of the region, in steps of 2 (whole 2 x 2 polarizer cells).",
        false,
        true,
        "WidthReg",
        &[two(), ("pMax", "WidthMaxNow".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("WidthReg", addr::WIDTH, 4, Access::Rw);
    x.swiss_knife(
        "WidthMaxNow",
        &[("S", "SensorWidthReg"), ("O", "OffsetXReg")],
        "S-O",
    );
    x.integer(
        "Height",
        "Height of the region, in steps of 2.",
        false,
        true,
        "HeightReg",
        &[two(), ("pMax", "HeightMaxNow".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("HeightReg", addr::HEIGHT, 4, Access::Rw);
    x.swiss_knife(
        "HeightMaxNow",
        &[("S", "SensorHeightReg"), ("O", "OffsetYReg")],
        "S-O",
    );
    x.integer(
        "OffsetX",
        "First column of the region, in steps of 2 (the polarizer cell stays aligned).",
        false,
        true,
        "OffsetXReg",
        &[("Min", "0".into()), ("pMax", "OffsetXMax".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("OffsetXReg", addr::OFFSET_X, 4, Access::Rw);
    x.swiss_knife(
        "OffsetXMax",
        &[("S", "SensorWidthReg"), ("W", "WidthReg")],
        "S-W",
    );
    x.integer(
        "OffsetY",
        "First row of the region, in steps of 2.",
        false,
        true,
        "OffsetYReg",
        &[("Min", "0".into()), ("pMax", "OffsetYMax".into()), inc()],
        Some("px"),
        None,
    );
    x.int_reg("OffsetYReg", addr::OFFSET_Y, 4, Access::Rw);
    x.swiss_knife(
        "OffsetYMax",
        &[("S", "SensorHeightReg"), ("H", "HeightReg")],
        "S-H",
    );
    let entries: Vec<(&str, u32, String)> = GevPixelFormat::ALL
        .iter()
        .map(|f| {
            let bits = format!("{}-bit ADC", f.adc_bits());
            let t = if f.polarized() {
                format!(
                    "LUCID's name for {}'s bytes ({bits}).",
                    f.packing().pfnc_name()
                )
            } else {
                format!("{} ({bits}).", f.name())
            };
            (f.name(), f.code(), t)
        })
        .collect();
    let e: Vec<(&str, u32, &str)> = entries
        .iter()
        .map(|(n, c, t)| (*n, *c, t.as_str()))
        .collect();
    x.enumeration(
        "PixelFormat",
        "Format of the pixels; the polarized names carry the same bytes as their Mono twins.",
        true,
        "PixelFormatReg",
        &e,
    );
    x.int_reg("PixelFormatReg", addr::PIXEL_FORMAT, 4, Access::Rw);
}

pub(super) fn acquisition(x: &mut X) {
    x.enumeration(
        "AcquisitionMode",
        "How many frames an AcquisitionStart gives.",
        true,
        "AcquisitionModeReg",
        &[
            ("Continuous", 0, "Frames until AcquisitionStop."),
            ("SingleFrame", 1, "One frame."),
            ("MultiFrame", 2, "AcquisitionFrameCount frames."),
        ],
    );
    x.int_reg("AcquisitionModeReg", addr::ACQUISITION_MODE, 4, Access::Rw);
    x.command(
        "AcquisitionStart",
        "Starts the acquisition.",
        false,
        "AcquisitionStartReg",
        1,
    );
    x.int_reg(
        "AcquisitionStartReg",
        addr::ACQUISITION_START,
        4,
        Access::Wo,
    );
    x.command(
        "AcquisitionStop",
        "Stops the acquisition after the frame in flight.",
        false,
        "AcquisitionStopReg",
        1,
    );
    x.int_reg("AcquisitionStopReg", addr::ACQUISITION_STOP, 4, Access::Wo);
    x.integer(
        "AcquisitionFrameCount",
        "Frames of a MultiFrame acquisition.",
        false,
        true,
        "AcquisitionFrameCountReg",
        &[("Min", "1".into()), ("Max", "65535".into())],
        None,
        None,
    );
    x.int_reg(
        "AcquisitionFrameCountReg",
        addr::ACQUISITION_FRAME_COUNT,
        4,
        Access::Rw,
    );
    x.boolean(
        "AcquisitionFrameRateEnable",
        "Paces frames at AcquisitionFrameRate (off: as fast as the device renders).",
        false,
        false,
        "FrameRateEnableReg",
    );
    x.int_reg("FrameRateEnableReg", addr::FRAME_RATE_ENABLE, 4, Access::Rw);
    x.float(
        "AcquisitionFrameRate",
        "Frame rate; reads as the rate delivered when the device cannot render as fast as asked.",
        "FrameRateReg",
        Some(registers::FRAME_RATE_RANGE),
        "Hz",
    );
    x.float_reg("FrameRateReg", addr::FRAME_RATE, Access::Rw);
    x.float(
        "AcquisitionResultingFrameRate",
        "Rate of the recent frames.",
        "ResultingFrameRateReg",
        None,
        "Hz",
    );
    x.float_reg(
        "ResultingFrameRateReg",
        addr::RESULTING_FRAME_RATE,
        Access::Ro,
    );
    x.enumeration(
        "TriggerSelector",
        "The trigger to configure.",
        false,
        "TriggerSelectorReg",
        &[("FrameStart", 0, "Starts one frame.")],
    );
    x.int_reg("TriggerSelectorReg", addr::TRIGGER_SELECTOR, 4, Access::Rw);
    x.enumeration(
        "TriggerMode",
        "On: each trigger starts one frame.",
        false,
        "TriggerModeReg",
        &[
            ("Off", 0, "Free running."),
            ("On", 1, "One frame per trigger."),
        ],
    );
    x.int_reg("TriggerModeReg", addr::TRIGGER_MODE, 4, Access::Rw);
    x.enumeration(
        "TriggerSource",
        "Where triggers come from.",
        false,
        "TriggerSourceReg",
        &[("Software", 0, "TriggerSoftware.")],
    );
    x.int_reg("TriggerSourceReg", addr::TRIGGER_SOURCE, 4, Access::Rw);
    x.command(
        "TriggerSoftware",
        "Triggers one frame.",
        false,
        "TriggerSoftwareReg",
        1,
    );
    x.int_reg("TriggerSoftwareReg", addr::TRIGGER_SOFTWARE, 4, Access::Wo);
    x.enumeration(
        "ExposureAuto",
        "Continuous: exposure from the sky (99th percentile at 70 % of full well).",
        false,
        "ExposureAutoReg",
        &[
            ("Off", 0, "ExposureTime."),
            ("Continuous", 2, "Every frame."),
        ],
    );
    x.int_reg("ExposureAutoReg", addr::EXPOSURE_AUTO, 4, Access::Rw);
    x.float(
        "ExposureTime",
        "Exposure time (under ExposureAuto: the last frame's).",
        "ExposureTimeReg",
        Some(registers::EXPOSURE_RANGE),
        "us",
    );
    x.float_reg("ExposureTimeReg", addr::EXPOSURE_TIME, Access::Rw);
}

pub(super) fn analog(x: &mut X) {
    x.float(
        "Gain",
        "Analog gain.",
        "GainReg",
        Some(registers::GAIN_RANGE),
        "dB",
    );
    x.float_reg("GainReg", addr::GAIN, Access::Rw);
    x.enumeration(
        "GainAuto",
        "Automatic gain (not modelled).",
        false,
        "GainAutoReg",
        &[("Off", 0, "Gain.")],
    );
    x.int_reg("GainAutoReg", addr::GAIN_AUTO, 4, Access::Rw);
    x.float(
        "BlackLevel",
        "Black level, DN at 12 bits (an 8-bit format shows it divided by 16).",
        "BlackLevelReg",
        Some(registers::BLACK_LEVEL_RANGE),
        "DN",
    );
    x.float_reg("BlackLevelReg", addr::BLACK_LEVEL, Access::Rw);
}
