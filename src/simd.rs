//! Run-time choice of the instruction set for the row kernels (`simd_dispatch!`): AVX-512,
//! AVX2 + FMA or plain x86-64, the same bits in every one (`docs/performance.md`).

/// Defines `$vis fn $name(args) -> ret` that runs a kernel built for the instruction set
/// [`simd`] chooses: AVX-512 (F, BW, DQ, VL with AVX2 and FMA), AVX2 with FMA, or plain x86-64.
/// The one way psns picks an instruction set; two forms:
///
/// * `fn name = body(args)`: the `#[inline(always)]` portable kernel `body`, built once per
///   instruction set. The loops vectorise in each build; all give the same bits: the kernels'
///   `mul_add` is exactly rounded with or without the instruction, plain `*` and `+` are never
///   fused, and division, square root, min, max and conversions are exact IEEE operations in
///   every instruction set (the `simd_paths_agree` tests check it). Every row kernel of the fast
///   path and the PSNS presets.
/// * `fn name = { avx512: f, avx2: g, plain: h }(args)`: a kernel written per instruction set
///   (intrinsics): `f` and `g` are `#[target_feature]` functions for AVX-512 and AVX2 (either may
///   be left out; the next lower level runs instead), `h` the portable one. Each must give the
///   same result as `h` (tested per kernel at every level, [`with_simd`]).
/// * `unsafe fn name = { ... }(level: Simd; args)`: the same with the level passed in (chosen
///   once by [`simd`] for a whole row, where a kernel called per few pixels cannot afford the
///   look-up); the caller guarantees `level` is at most what the CPU has.
///
/// `PSNS_SIMD` and [`with_simd`] cap the level, so tests and benchmarks run every build.
#[macro_export]
macro_rules! simd_dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident = $body:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?) => {
        $(#[$m])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx512($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $body($($arg),*)
                }
                match $crate::simd::simd() {
                    // SAFETY: `simd` never returns more than the CPU has
                    $crate::simd::Simd::Avx512 => return unsafe { avx512($($arg),*) },
                    // SAFETY: as above
                    $crate::simd::Simd::Avx2 => return unsafe { avx2($($arg),*) },
                    $crate::simd::Simd::Plain => {}
                }
            }
            $body($($arg),*)
        }
    };
    ($(#[$m:meta])* $vis:vis unsafe fn $name:ident = {
        $(avx512: $a512:path,)? $(avx2: $a2:path,)? plain: $plain:path $(,)?
    }($level:ident: Simd; $($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?) => {
        $(#[$m])*
        #[allow(clippy::too_many_arguments)]
        $vis unsafe fn $name($level: $crate::simd::Simd, $($arg: $ty),*) $(-> $ret)? {
            debug_assert!($level <= $crate::simd::Simd::detected());
            // one call with the arguments, for each level's function
            macro_rules! call {
                ($f:path) => {
                    $f($($arg),*)
                };
            }
            #[cfg(target_arch = "x86_64")]
            {
                $(if $level >= $crate::simd::Simd::Avx512 {
                    // SAFETY: the caller's contract: `level` is at most what the CPU has
                    #[allow(unused_unsafe)]
                    return unsafe { call!($a512) };
                })?
                $(if $level >= $crate::simd::Simd::Avx2 {
                    // SAFETY: as above
                    #[allow(unused_unsafe)]
                    return unsafe { call!($a2) };
                })?
            }
            let _ = $level;
            call!($plain)
        }
    };
    ($(#[$m:meta])* $vis:vis fn $name:ident = {
        $(avx512: $a512:path,)? $(avx2: $a2:path,)? plain: $plain:path $(,)?
    }($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?) => {
        $(#[$m])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            // one call with the arguments, for each level's function
            macro_rules! call {
                ($f:path) => {
                    $f($($arg),*)
                };
            }
            #[cfg(target_arch = "x86_64")]
            {
                let _level = $crate::simd::simd();
                $(if _level >= $crate::simd::Simd::Avx512 {
                    // SAFETY: `simd` never returns more than the CPU has
                    #[allow(unused_unsafe)]
                    return unsafe { call!($a512) };
                })?
                $(if _level >= $crate::simd::Simd::Avx2 {
                    // SAFETY: as above
                    #[allow(unused_unsafe)]
                    return unsafe { call!($a2) };
                })?
            }
            call!($plain)
        }
    };
}
pub use crate::simd_dispatch;

/// Instruction sets the row kernels are built for (`simd_dispatch!`), in increasing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Simd {
    /// Baseline x86-64 (SSE2), and every other architecture.
    Plain,
    /// AVX2 and FMA.
    Avx2,
    /// AVX-512 F, BW, DQ and VL (with AVX2 and FMA).
    Avx512,
}

impl Simd {
    /// The best the CPU has.
    pub fn detected() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let avx2 = has!("avx2") && has!("fma");
            if avx2 && has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl") {
                return Simd::Avx512;
            }
            if avx2 {
                return Simd::Avx2;
            }
        }
        Simd::Plain
    }

    /// Every instruction set this CPU can run, plain first (for comparing the builds).
    pub fn available() -> Vec<Simd> {
        [Simd::Plain, Simd::Avx2, Simd::Avx512]
            .into_iter()
            .filter(|&l| l <= Simd::detected())
            .collect()
    }

    /// Parses `plain`, `avx2` or `avx512`.
    pub fn parse(s: &str) -> Option<Simd> {
        match s.trim().to_ascii_lowercase().as_str() {
            "plain" => Some(Simd::Plain),
            "avx2" => Some(Simd::Avx2),
            "avx512" => Some(Simd::Avx512),
            _ => None,
        }
    }
}

thread_local! {
    static SIMD_OVERRIDE: std::cell::Cell<Option<Simd>> = const { std::cell::Cell::new(None) };
}

/// The instruction set of the row kernels: the best the CPU has, capped by the environment
/// variable `PSNS_SIMD` (`plain`, `avx2` or `avx512`, read once; for comparing and timing the
/// builds) and, on the calling thread only, by [`with_simd`]. Every choice gives the same bits.
pub fn simd() -> Simd {
    static PROCESS: std::sync::OnceLock<Simd> = std::sync::OnceLock::new();
    let p = *PROCESS.get_or_init(|| {
        let cpu = Simd::detected();
        std::env::var("PSNS_SIMD")
            .ok()
            .and_then(|v| Simd::parse(&v))
            .map_or(cpu, |cap| cap.min(cpu))
    });
    SIMD_OVERRIDE.with(|o| o.get()).map_or(p, |cap| cap.min(p))
}

/// Runs `f` with the row kernels called on this thread (not on rayon's workers) capped at `s`
/// (for tests that compare the builds).
pub fn with_simd<R>(s: Simd, f: impl FnOnce() -> R) -> R {
    let prev = SIMD_OVERRIDE.with(|o| o.replace(Some(s)));
    struct Restore(Option<Simd>);
    impl Drop for Restore {
        fn drop(&mut self) {
            SIMD_OVERRIDE.with(|o| o.set(self.0));
        }
    }
    let _restore = Restore(prev);
    f()
}
