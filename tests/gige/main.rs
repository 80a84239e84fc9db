//! `psns gige`: the GigE Vision protocol module without sockets, and the device against Aravis,
//! a GenICam client nobody here wrote.

mod chunks;
mod codecs;
mod completeness;
mod device;
mod harness;
