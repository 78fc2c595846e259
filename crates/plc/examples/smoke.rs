fn main() {
    let path = std::env::args().nth(1).unwrap();
    match rtcnc_plc::compile_file(std::path::Path::new(&path)) {
        Ok(p) => println!("ok: {} slots, tasks {:?}", p.memory_slots(), p.tasks()),
        Err(e) => println!("{e}"),
    }
}
