//! The state machine target: an Amazon States Language definition, loaded and checked the way
//! the emulator loads `infra/statemachine.asl.json`.

use asl_interpreter::{Orchestrator, OrchestratorOptions};

use crate::assert_one_line;

/// ASL target: the input is the definition text; it loads or fails with a one-line error, and a
/// loaded machine lists its functions.
pub fn asl(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Orchestrator::new(text, OrchestratorOptions::default()) {
        Err(e) => assert_one_line("state machine", &e.to_string()),
        Ok(machine) => {
            let _ = machine.functions();
        }
    }
}
