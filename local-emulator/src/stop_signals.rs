//! Ctrl-C (SIGINT), SIGTERM and SIGHUP stop a run alike (it cleans up after itself), and the
//! message says how to quit at once after the signal that came.

use tokio::signal::unix::{SignalKind, signal};

/// A signal that asks a run to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopSignal {
    /// SIGINT: Ctrl-C in the terminal.
    Interrupt,
    /// SIGTERM: `kill`, service managers, containers stopping.
    Terminate,
    /// SIGHUP: the terminal went away.
    Hangup,
}

impl StopSignal {
    /// How to quit at once once this signal began a stop.
    pub fn quit_at_once(self) -> &'static str {
        match self {
            Self::Interrupt => "press Ctrl-C again to quit at once",
            Self::Terminate => "send SIGTERM again or press Ctrl-C to quit at once",
            Self::Hangup => "send SIGHUP again or press Ctrl-C to quit at once",
        }
    }

    /// The exit status of a process this signal ends at once: 128 plus the signal's number, as
    /// a shell reports it.
    pub fn exit_code(self) -> i32 {
        match self {
            Self::Interrupt => 130,
            Self::Terminate => 143,
            Self::Hangup => 129,
        }
    }
}

/// From now on, SIGINT, SIGTERM and SIGHUP no longer end the process: each calls `handler`
/// (on a thread of its own) with the signal that came. Fails if a signal cannot be watched; the
/// default behaviour then stays.
pub fn on_stop_signals(
    mut handler: impl FnMut(StopSignal) + Send + 'static,
) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()?;
    let (mut interrupt, mut terminate, mut hangup) = {
        let _inside = runtime.enter();
        (
            signal(SignalKind::interrupt())?,
            signal(SignalKind::terminate())?,
            signal(SignalKind::hangup())?,
        )
    };
    std::thread::Builder::new()
        .name("hort-signals".to_owned())
        .spawn(move || {
            runtime.block_on(async move {
                loop {
                    let stop = tokio::select! {
                        Some(()) = interrupt.recv() => StopSignal::Interrupt,
                        Some(()) = terminate.recv() => StopSignal::Terminate,
                        Some(()) = hangup.recv() => StopSignal::Hangup,
                        else => return,
                    };
                    handler(stop);
                }
            });
        })?;
    Ok(())
}
