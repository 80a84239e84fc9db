//! The render thread and the write loop of `psns stream`: frames come from the thread in order
//! (pose k+1 rendered while frame k is written), are paced by `--rate` and written into the
//! output, and a stop signal ends the run by the rules of [`super::run_stream`].

use super::output::{OutFrame, Output};
use super::signals::stop_signal;
use super::{
    host_monotonic_ns, FrameMaker, Payload, Rendered, StreamOptions, StreamSummary, LATE_TOLERANCE,
    PAYLOAD_BUFFERS,
};
use crate::cli::progress::Progress;
use psns::error::{Error, Result};
use psns::stream::FLAG_LAST;
use psns::trajectory::Pose;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The render thread and what comes back from it: pose k+1 is rendered while frame k is
/// written; written payloads go back for reuse.
pub(super) struct Frames {
    rx: Receiver<Result<Rendered>>,
    spare: SyncSender<Payload>,
    /// The render thread holds a pose it has not sent as a frame yet.
    busy: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<()>,
}

/// What the render thread delivered next.
pub(super) enum Next {
    Frame(Box<Result<Rendered>>),
    /// The poses ended (or the render thread is gone).
    End,
    /// A signal asked the stream to stop.
    Stopped(i32),
}

impl Frames {
    /// Starts the render thread on `poses`, `limit` frames at most. It stops before a new pose
    /// once a stop signal came.
    pub(super) fn start(
        mut maker: FrameMaker,
        mut poses: Box<dyn Iterator<Item = Result<Pose>> + Send>,
        lookahead: bool,
        limit: Option<u64>,
    ) -> Result<Frames> {
        let (tx, rx) = sync_channel::<Result<Rendered>>(1);
        let (spare, spare_rx) = sync_channel::<Payload>(PAYLOAD_BUFFERS);
        maker.spare = Some(spare_rx);
        let busy = Arc::new(AtomicBool::new(false));
        let busy_r = busy.clone();
        let thread = std::thread::Builder::new()
            .name("psns-render".into())
            .spawn(move || {
                let mut peeked: Option<Option<Result<Pose>>> = None;
                let mut k: u64 = 0;
                loop {
                    if limit == Some(k) || stop_signal().is_some() {
                        return;
                    }
                    let Some(item) = peeked.take().unwrap_or_else(|| poses.next()) else {
                        return;
                    };
                    busy_r.store(true, Ordering::SeqCst);
                    let pose = match item {
                        Ok(p) => p,
                        Err(e) => {
                            let _ = tx.send(Err(e));
                            return;
                        }
                    };
                    let last = if limit == Some(k + 1) {
                        true
                    } else if lookahead {
                        let next = poses.next();
                        let end = next.is_none();
                        peeked = Some(next);
                        end
                    } else {
                        false
                    };
                    let r = maker.render(k, &pose, last);
                    let failed = r.is_err();
                    let sent = tx.send(r).is_ok();
                    busy_r.store(false, Ordering::SeqCst);
                    if !sent || failed {
                        return; // writer gone (reader closed) or render error sent
                    }
                    k += 1;
                }
            })
            .map_err(|e| Error::io("starting the render thread", e))?;
        Ok(Frames {
            rx,
            spare,
            busy,
            thread,
        })
    }

    /// Waits for the next frame, waking up now and then to see whether a signal asked to stop
    /// (a frame received is never dropped: the stop is seen before the next one).
    pub(super) fn next(&self) -> Next {
        loop {
            if let Some(sig) = stop_signal() {
                return Next::Stopped(sig);
            }
            match self.rx.recv_timeout(Duration::from_millis(100)) {
                Ok(r) => return Next::Frame(Box::new(r)),
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return Next::End,
            }
        }
    }

    /// After a stop signal: the frames the render thread already holds (queued, or being
    /// rendered), up to the first failure. A thread waiting for a pose holds none.
    fn drain(&self) -> Vec<Rendered> {
        let mut v = Vec::new();
        loop {
            match self.rx.recv_timeout(Duration::from_millis(20)) {
                Ok(Ok(r)) => v.push(r),
                Ok(Err(_)) | Err(RecvTimeoutError::Disconnected) => return v,
                Err(RecvTimeoutError::Timeout) if !self.busy.load(Ordering::SeqCst) => return v,
                Err(RecvTimeoutError::Timeout) => {}
            }
        }
    }

    /// Waits for the render thread, which has ended.
    pub(super) fn join(self) {
        drop(self.rx);
        drop(self.spare);
        let _ = self.thread.join();
    }
}

/// How the frames ended.
pub(super) enum End {
    /// The poses or `--frames` ended.
    Done,
    /// A stop signal: the frames in hand were written, the last flagged LAST.
    Finished(i32),
    /// A stop signal ends the run early: the output is to be marked aborted.
    Stopped(i32),
}

/// Writes frames as they arrive, paced by `--rate`, counting them (and late ones) in `summary`.
/// A payload buffer goes back to the render thread once `retain` more frames are written after
/// it (a pipe holds its pages, [`Output::splice_payloads`]); the last `retain` are never freed.
pub(super) fn write_loop(
    out: &mut Output,
    mut first: Option<Rendered>,
    frames: &Frames,
    retain: usize,
    opts: &StreamOptions,
    progress: &mut Progress,
    summary: &mut StreamSummary,
) -> Result<End> {
    let mut t0: Option<Instant> = None;
    let mut write = |r: &mut Rendered, paced: bool, summary: &mut StreamSummary| -> Result<()> {
        if let (Some(rate), true) = (opts.rate_fps, paced) {
            let now = Instant::now();
            let t0 = *t0.get_or_insert(now);
            let due = t0 + Duration::from_secs_f64(summary.frames as f64 / rate);
            if now > due + LATE_TOLERANCE {
                summary.late_frames += 1;
            } else if due > now {
                std::thread::sleep(due - now);
            }
        }
        if opts.stamp_host_time {
            r.meta.host_time_ns = host_monotonic_ns();
        }
        let truth = r.truth.as_ref().map(|(d, a)| (&d[..], &a[..]));
        out.write(OutFrame {
            meta: &r.meta,
            pixels: r.payload.pixels(),
            crc: r.crc,
            truth,
        })?;
        summary.frames += 1;
        progress.inc(1);
        Ok(())
    };
    let mut held = HeldPayloads {
        queue: std::collections::VecDeque::with_capacity(retain + 1),
    };
    loop {
        let r = match first.take() {
            Some(r) => Ok(r),
            None => match frames.next() {
                Next::Frame(r) => *r,
                Next::End => return Ok(End::Done),
                Next::Stopped(sig) => {
                    // SIGINT and SIGTERM end an open-ended run as `ros2 bag record` does; a
                    // run of N frames stopped early, or a lost terminal, is cut short
                    if opts.frames.is_some() || !matches!(sig, libc::SIGINT | libc::SIGTERM) {
                        return Ok(End::Stopped(sig));
                    }
                    let mut rest = frames.drain();
                    if let Some(last) = rest.last_mut() {
                        last.meta.flags |= FLAG_LAST;
                    }
                    for mut r in rest {
                        let written = write(&mut r, false, summary);
                        held.hold(r.payload, retain, frames);
                        written?;
                    }
                    return Ok(End::Finished(sig));
                }
            },
        };
        let mut r = r?;
        let written = write(&mut r, true, summary);
        held.hold(r.payload, retain, frames);
        written?;
    }
}

/// Payload buffers a pipe may still refer to: never freed (freed memory is soon reused, and
/// the reader may not have read them yet), so they live until the process ends.
struct HeldPayloads {
    queue: std::collections::VecDeque<Payload>,
}

impl HeldPayloads {
    /// Holds a written payload; the one `retain` frames older goes back to the render thread.
    fn hold(&mut self, p: Payload, retain: usize, frames: &Frames) {
        self.queue.push_back(p);
        while self.queue.len() > retain {
            if let Some(p) = self.queue.pop_front() {
                let _ = frames.spare.try_send(p);
            }
        }
    }
}

impl Drop for HeldPayloads {
    fn drop(&mut self) {
        for p in self.queue.drain(..) {
            std::mem::forget(p);
        }
    }
}
