"""Write rosbag2 bags with the independent Python library rosbags (crates/bag/tests/interop.rs).

  make_bags.py FRAMES.raw STAMPS.json WIDTH HEIGHT OUT_DIR

FRAMES.raw holds N RGB8 frames back to back; STAMPS.json the N capture stamps [ns]. Writes, under
OUT_DIR, one bag per storage/encoding the labs record:

  mcap_rgb8_zstd/   MCAP, zstd chunks, sensor_msgs/Image rgb8 on /gs/image_raw, plus a
                    std_msgs/String topic /chatter (a type the Rust side does not know)
  sqlite_bgr8/      sqlite3 (.db3, Humble's default), sensor_msgs/Image bgr8, rows padded (step+4)
  mcap_jpeg/        MCAP, sensor_msgs/CompressedImage "jpeg" (encoded by OpenCV)

header.frame_id is gs_optical_frame, header.stamp and the bag timestamp are the capture stamps.
"""
import json
import sys
from pathlib import Path

import cv2
import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_HUMBLE)
Image = TS.types['sensor_msgs/msg/Image']
CompressedImage = TS.types['sensor_msgs/msg/CompressedImage']
Header = TS.types['std_msgs/msg/Header']
Time = TS.types['builtin_interfaces/msg/Time']
String = TS.types['std_msgs/msg/String']


def header(ns):
    return Header(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
                  frame_id='gs_optical_frame')


def main():
    raw, stamps, w, h, out = sys.argv[1:6]
    w, h = int(w), int(h)
    stamps = json.loads(Path(stamps).read_text())
    frames = np.fromfile(raw, dtype=np.uint8).reshape(len(stamps), h, w, 3)
    out = Path(out)

    wr = Writer(out / 'mcap_rgb8_zstd', version=9, storage_plugin=StoragePlugin.MCAP)
    wr.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)  # zstd chunks
    with wr:
        img = wr.add_connection('/gs/image_raw', Image.__msgtype__, typestore=TS)
        chat = wr.add_connection('/chatter', String.__msgtype__, typestore=TS)
        for i, (f, ns) in enumerate(zip(frames, stamps)):
            m = Image(header=header(ns), height=h, width=w, encoding='rgb8', is_bigendian=0,
                      step=w * 3, data=f.reshape(-1))
            wr.write(img, ns, TS.serialize_cdr(m, Image.__msgtype__))
            if i % 10 == 0:
                wr.write(chat, ns, TS.serialize_cdr(String(data=f'frame {i}'), String.__msgtype__))

    with Writer(out / 'sqlite_bgr8', version=8, storage_plugin=StoragePlugin.SQLITE3) as wr:
        img = wr.add_connection('/gs/image_raw', Image.__msgtype__, typestore=TS)
        for f, ns in zip(frames, stamps):
            bgr = np.zeros((h, w * 3 + 4), dtype=np.uint8)
            bgr[:, : w * 3] = f[:, :, ::-1].reshape(h, w * 3)
            m = Image(header=header(ns), height=h, width=w, encoding='bgr8', is_bigendian=0,
                      step=w * 3 + 4, data=bgr.reshape(-1))
            wr.write(img, ns, TS.serialize_cdr(m, Image.__msgtype__))

    with Writer(out / 'mcap_jpeg', version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        img = wr.add_connection('/gs/image_raw/compressed', CompressedImage.__msgtype__,
                                typestore=TS)
        for f, ns in zip(frames, stamps):
            ok, jpg = cv2.imencode('.jpg', f[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
            assert ok
            m = CompressedImage(header=header(ns), format='jpeg',
                                data=np.frombuffer(jpg.tobytes(), dtype=np.uint8))
            wr.write(img, ns, TS.serialize_cdr(m, CompressedImage.__msgtype__))


if __name__ == '__main__':
    main()
