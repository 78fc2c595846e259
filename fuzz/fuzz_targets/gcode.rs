#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| rtcnc_fuzz::gcode::run(data));
