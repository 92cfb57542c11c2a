//! Host-side simulator for controller-core (filled by the hil-sim issue).
#![deny(missing_docs)]
