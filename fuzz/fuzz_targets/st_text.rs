#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| rtcnc_fuzz::st_text::run(data));
