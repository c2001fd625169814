//! Entry points for the fuzz targets in crates/bag/fuzz (cargo fuzz) and for the seeded smoke
//! test that runs the same functions in CI. Each takes arbitrary bytes and must return without
//! panicking and without allocating more than a small multiple of its input.

use crate::ros::{CompressedImage, Image, RosMessage};

/// Parse an MCAP stream; decode every message that claims a known type.
pub fn mcap(data: &[u8]) {
    if let Ok((msgs, _)) = crate::read::read_mcap_bytes(data) {
        for m in msgs {
            cdr_as(&m.topic.type_name, &m.data);
        }
    }
}

fn cdr_as(type_name: &str, data: &[u8]) {
    match type_name {
        "sensor_msgs/msg/Image" => {
            if let Ok(img) = Image::from_cdr(data) {
                let _ = crate::image::image_to_frame(&img.view(), "fuzz", 0);
            }
        }
        "sensor_msgs/msg/CompressedImage" => {
            if let Ok(img) = CompressedImage::from_cdr(data) {
                let _ = crate::image::compressed_to_frame(&img.view(), "fuzz", 0);
            }
        }
        _ => {}
    }
}

/// Decode the bytes as every message type this crate knows.
pub fn cdr(data: &[u8]) {
    cdr_as("sensor_msgs/msg/Image", data);
    let _ = CompressedImage::from_cdr(data);
    // Every message of msg/unitac_msgs, from the same definition as its codec.
    macro_rules! decode_each {
        (
            messages { $( $msg:ident [$to:ident, $from:ident] { $($fields:tt)* } )* }
            enums { $($e:tt)* }
        ) => {
            $( let _ = <unitac_core::msg::$msg as RosMessage>::from_cdr(data); )*
        };
    }
    unitac_core::for_each_message!(decode_each);
}

/// Parse the bytes as metadata.yaml.
pub fn metadata(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = crate::metadata::parse(text);
    }
}
