//! Writing a run's frames on their own thread, one frame at a time, while the next frame renders:
//! at most one frame is being written and one rendered, so a run holds two frames, not all. A
//! written frame's planes come back for a later frame to render into.

use std::sync::mpsc::{self, Receiver, SyncSender};
use std::thread::JoinHandle;

use amr_render::output::legend::Legend;
use amr_render::output::FrameBuffer;
use amr_render::Rendered;
use anyhow::{bail, Context};

use crate::outputs::{self, FrameFiles};

/// A rendered frame and what to write it with.
pub struct FrameJob {
    /// Where it goes.
    pub files: FrameFiles,
    /// The frame.
    pub rendered: Rendered,
    /// Its EXR header's text attributes.
    pub header: Vec<(String, String)>,
    /// What its pictures show over it (`None`: nothing).
    pub legend: Option<Legend>,
}

/// The thread that writes frames, in the order given.
///
/// A frame handed over waits until the previous one is written. The first write that fails
/// stops the writer: the frames after it are not written, and the error (which names its file)
/// comes back from the next [`FrameWriter::write`] or from [`FrameWriter::finish`]. Each file is
/// written whole or not at all ([`outputs::write_frame`]).
pub struct FrameWriter {
    jobs: Option<SyncSender<FrameJob>>,
    written: Receiver<FrameBuffer>,
    thread: Option<JoinHandle<anyhow::Result<()>>>,
}

impl FrameWriter {
    /// Starts the writer.
    pub fn start() -> anyhow::Result<FrameWriter> {
        // No buffer: a send completes when the writer takes the frame, that is once it has
        // written the previous one.
        let (jobs, queue) = mpsc::sync_channel::<FrameJob>(0);
        let (done, written) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("frame writer".into())
            .spawn(move || {
                for job in queue {
                    let legend = job.legend.as_ref();
                    outputs::write_frame(&job.files, &job.rendered, &job.header, legend)?;
                    // The run may have ended; then the planes are simply dropped.
                    let _ = done.send(job.rendered.frame);
                }
                Ok(())
            })
            .context("cannot start the thread that writes frames")?;
        Ok(FrameWriter {
            jobs: Some(jobs),
            written,
            thread: Some(thread),
        })
    }

    /// Hands `job` to the writer once it has written the previous frame; returns that write's
    /// error, if it failed.
    pub fn write(&mut self, job: FrameJob) -> anyhow::Result<()> {
        let Some(jobs) = &self.jobs else {
            unreachable!("the writer takes frames until it is finished");
        };
        if let Err(mpsc::SendError(job)) = jobs.send(job) {
            // The writer has stopped: a write failed, and that is the error to report.
            self.join()?;
            bail!(
                "{}: not written: the frame writer stopped",
                job.files.exr.display()
            );
        }
        Ok(())
    }

    /// The planes of a frame written since the last call, if any, for the next frame to render
    /// into. Once a frame has been handed over, the one before it has been written and its
    /// planes are here.
    pub fn written_planes(&self) -> Option<FrameBuffer> {
        self.written.try_recv().ok()
    }

    /// Waits for every frame handed over to be written.
    pub fn finish(mut self) -> anyhow::Result<()> {
        self.join()
    }

    /// Closes the queue and waits for the writer: its result, or its panic passed on.
    fn join(&mut self) -> anyhow::Result<()> {
        self.jobs = None;
        match self.thread.take().map(JoinHandle::join) {
            None => Ok(()),
            Some(Ok(written)) => written,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
        }
    }
}

impl Drop for FrameWriter {
    /// A run that stops for another reason still completes the frame being written (a process
    /// that exits mid-write would leave its temporary file behind) and says if that write failed.
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(Ok(Err(e))) = self.thread.take().map(JoinHandle::join) {
            eprintln!("Error: {e:#}");
        }
    }
}
