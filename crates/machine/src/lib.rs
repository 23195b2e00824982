//! dbbcal-machine: the pure math of the machine kinds (issue 29).
