//! A failed FMI call: which function, what it returned, and whether the FMU asks to end the
//! simulation — static texts, so that a failing release allocates nothing until the component
//! says why (with the time and what the FMU logged, `component`).

use std::fmt;

use fmi::fmi2::Fmi2Error;
use fmi::fmi3::Fmi3Error;

/// A failed FMI call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CallError {
    /// The FMI function (`fmi2DoStep`).
    pub call: &'static str,
    /// What it returned (`fmi2Discard`); `None`: it returned OK but asks to terminate.
    pub status: Option<&'static str>,
    /// How the FMU asks the simulation to end, if it does: FMI 2's `fmi2Terminated` status
    /// after a discarded step, FMI 3's `terminateSimulation`.
    pub terminate: Option<&'static str>,
}

impl CallError {
    /// `call` returned the FMI 2 status of `e`.
    pub fn fmi2(call: &'static str, e: &Fmi2Error) -> CallError {
        let status = match e {
            Fmi2Error::Discard => "fmi2Discard",
            Fmi2Error::Error => "fmi2Error",
            Fmi2Error::Fatal => "fmi2Fatal",
            Fmi2Error::TypesPlatformMismatch(_) => "a types platform this host does not use",
        };
        CallError {
            call,
            status: Some(status),
            terminate: None,
        }
    }

    /// `call` returned the FMI 3 status of `e`.
    pub fn fmi3(call: &'static str, e: &Fmi3Error) -> CallError {
        let status = match e {
            Fmi3Error::Discard => "fmi3Discard",
            Fmi3Error::Error => "fmi3Error",
            Fmi3Error::Fatal => "fmi3Fatal",
        };
        CallError {
            call,
            status: Some(status),
            terminate: None,
        }
    }

    /// A call the host refused before making it (a value the FMU's type cannot hold).
    pub fn refused(call: &'static str, why: &'static str) -> CallError {
        CallError {
            call,
            status: Some(why),
            terminate: None,
        }
    }
}

impl fmt::Display for CallError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.status {
            Some(status) => write!(f, "{} failed with {status}", self.call)?,
            None => f.write_str(self.call)?,
        }
        match self.terminate {
            Some(how) => write!(f, ": the FMU asks to terminate ({how})"),
            None => Ok(()),
        }
    }
}

impl std::error::Error for CallError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_call_names_the_function_and_its_status() {
        let sut = CallError::fmi2("fmi2DoStep", &Fmi2Error::Discard);
        assert_eq!(sut.to_string(), "fmi2DoStep failed with fmi2Discard");
        let sut = CallError {
            terminate: Some("fmi2Terminated"),
            ..sut
        };
        assert_eq!(
            sut.to_string(),
            "fmi2DoStep failed with fmi2Discard: the FMU asks to terminate (fmi2Terminated)"
        );
        let sut = CallError::fmi3("fmi3SetFloat64", &Fmi3Error::Error);
        assert_eq!(sut.to_string(), "fmi3SetFloat64 failed with fmi3Error");
        let sut = CallError {
            call: "fmi3DoStep",
            status: None,
            terminate: Some("terminateSimulation"),
        };
        assert_eq!(
            sut.to_string(),
            "fmi3DoStep: the FMU asks to terminate (terminateSimulation)"
        );
    }
}
