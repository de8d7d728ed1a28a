//! Fuzzes the frame decoder and the board application with arbitrary bytes:
//! nothing may panic, every decoded message must re-encode to a frame that
//! decodes to itself, the counters must account for every non-empty frame,
//! and the board's outputs must stay within the pair rule and the supply.
#![no_main]
use firmware::app::{App, NoSensors};
use firmware::protocol::{encode_frame, Accept, FrameDecoder, MAX_FRAME};
use firmware::time::Instant;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut dec = FrameDecoder::new(Accept::Any);
    let mut frames = 0u32;
    for &b in data {
        if let Some(r) = dec.push(b) {
            frames += 1;
            if let Ok(m) = r {
                let mut out = [0u8; MAX_FRAME];
                let n = encode_frame(&m, &mut out);
                assert!(n > 0);
                let back = FrameDecoder::decode(&out[..n - 1], Accept::Any).expect("re-encoded frame decodes");
                assert_eq!(format!("{back:?}"), format!("{m:?}"));
            }
        }
    }
    let s = dec.stats();
    assert_eq!(
        frames,
        s.frames_ok + s.crc_errors + s.cobs_errors + s.overfull + s.malformed
    );

    // The same bytes into the board application, time advancing 1 ms per byte.
    let Ok(mut app) = App::new() else { return };
    for (i, &b) in data.iter().enumerate() {
        let now = Instant::from_millis(i as u64);
        app.on_byte(b, now, &mut |_f: &[u8]| {});
        app.poll(now, &mut NoSensors, &mut |_f: &[u8]| {});
        // Both coils of a pair only for a plane in open-loop drive mode.
        let driven = app.drive_planes();
        for (p, [a, b]) in app.outputs().into_iter().enumerate() {
            let (a, b) = (a.volts(), b.volts());
            assert!(a == 0.0 || b == 0.0 || driven & (1 << p) != 0);
            assert!((0.0..=5.0).contains(&a) && (0.0..=5.0).contains(&b));
        }
    }
});
