#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets into tests/data/fuzz/<target>/ (a few small files
each), from the test data and by hand. Run from the repository root; the files are committed, so
this only needs rerunning when a target's input format changes."""
import os, shutil, struct, subprocess, zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "tests", "data", "fuzz")


def put(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def read(rel):
    with open(os.path.join(ROOT, rel), "rb") as f:
        return f.read()


shutil.rmtree(OUT, ignore_errors=True)

# NMEA: the test log, a part of it with arrival prefixes, sentences of every type read.
nmea = read("tests/data/nav/receiver.nmea")
lines = nmea.split(b"\n")
prefixed = b"\n".join(b"%d %s" % (1700000000000000000 + 100000000 * i, l) for i, l in enumerate(lines[:12]))
hand = ("$GNGGA,120000.00,5100.0000000,N,00100.0000000,W,4,12,0.7,6967.1102,M,36.003,M,,*5B\r\n"
        "$GNRMC,120000.00,A,5100.0000000,N,00100.0000000,W,311.06,90.0,010624,,,D*5D\r\n"
        "$GNVTG,90.0,T,,M,311.06,N,576.08,K,D*2F\r\n$GNHDT,90.01,T*1A\r\n"
        "$GNGST,120000.00,0.01,0.01,0.01,0.0,0.011,0.012,0.02*4F\r\n"
        "$GNZDA,120000.00,01,06,2024,00,00*7E\r\n")
for t in ("fuzz_nmea", "fuzz_nmea_stream"):
    put(t, "receiver.nmea", nmea)
    put(t, "prefixed.nmea", prefixed)
    put(t, "types.nmea", hand)

# IMU CSV and the other nav CSVs (first byte '0' solution, '1' frame index, '2' camera poses).
imu = ("# clock: gps\n# sensor: fuzz\nt_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n"
       "1400000000000000000,0.005,1e-05,-2e-05,3e-06,0.001,0.0,-0.049\n"
       "1400000000005000000,0.005,1.1e-05,-2e-05,3e-06,0.001,0.0,-0.049\n"
       "1400000000015000000,0.005,1.2e-05,-2e-05,3e-06,0.001,0.0,-0.049\n")
put("fuzz_imu_csv", "imu.csv", imu)
put("fuzz_imu_csv", "arrival.csv",
    "t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,arrival_ns\n"
    "5000000,0.005,0,0,0,0,0,-0.049,5100000\n5000000,0.005,0,0,0,0,0,-0.049,5200000\n"
    "4000000,0.005,0,0,0,0,0,-0.049,5300000\n")
put("fuzz_nav_csv", "solution.csv",
    "0# clock: gps\nt_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,"
    "sigma_n_m,sigma_e_m,sigma_d_m,sigma_yaw_deg,sigma_pitch_deg,sigma_roll_deg\n"
    "1000000000,51,-1,7000,0,160,0,90,0,0,0.01,0.01,0.02,0.1,0.1,0.1\n"
    "1100000000,51,-0.9999,7000,0,160,0,90,0,0,,,,,,\n")
put("fuzz_nav_csv", "frames.csv",
    "1# clock: device\nsequence,camera,t_ns,file\n0,0,1000,left/0000.png\n0,1,1003,right/0000.png\n"
    "1,0,34000,left/0001.png\n")
put("fuzz_nav_csv", "poses.csv",
    "2sequence,camera,t_ns,t_nav_ns,x_m,y_m,z_m,qw,qx,qy,qz,sigma_pos_m,sigma_att_deg,"
    "boom_elevation_deg,boom_azimuth_deg,boom_extension_m\n"
    "0,0,1000,1400000000000001000,0.5,12,30,1,0,0,0,0.02,0.1,30,0,4\n"
    "0,1,1003,1400000000000001003,-0.5,12,30,0.7071,0,0.7071,0,,,,,\n")

# IMU datagrams: [u16 length | 0x8000 to fix the CRC][bytes], after a restart byte.
def datagram(n, seq, t0, clock=4, crc_ok=True):
    b = b"AGIM" + bytes([1, 1, clock, n]) + struct.pack("<Q", seq)
    for k in range(n):
        b += struct.pack("<qd3d3d", t0 + 5000000 * k, 0.005, 1e-5, -2e-5, 3e-6, 0.001, 0.0, -0.049)
    return b + struct.pack("<I", zlib.crc32(b) if crc_ok else 0)

def framed(d, fix=False):
    return struct.pack("<H", len(d) | (0x8000 if fix else 0)) + d

put("fuzz_imu_datagram", "one.bin", b"\x7d" + framed(datagram(1, 0, 1000000000)))
put("fuzz_imu_datagram", "gap.bin",
    b"\x10" + framed(datagram(3, 0, 1000000000)) + framed(datagram(2, 5, 1025000000)) +
    framed(datagram(1, 4, 1020000000)))
put("fuzz_imu_datagram", "fixcrc.bin", b"\x01" + framed(datagram(2, 7, 1000000000, clock=3, crc_ok=False), True))

# gpsd reports, one per line, as gpsd sends them.
gpsd = "\n".join([
    '{"class":"VERSION","release":"3.22","rev":"3.22","proto_major":3,"proto_minor":14}',
    '{"class":"SKY","device":"/dev/ttyACM0","hdop":0.7,"satellites":[{"PRN":1,"el":10,"az":20,"ss":30,"used":true},{"PRN":2,"el":10,"az":20,"ss":30,"used":false}]}',
    '{"class":"TPV","device":"/dev/pts/7","status":3,"mode":3,"time":"2024-06-01T12:00:00.800Z","ept":0.005,"lat":50.999999942,"lon":-0.998112821,"altHAE":7003.1133,"altMSL":6967.1102,"track":89.9913,"speed":160.022,"geoidSep":36.003,"velN":0.1,"velE":160.0,"velD":0.0,"leapseconds":18}',
    '{"class":"GST","device":"/dev/pts/7","time":"2024-06-01T12:00:00.800Z","major":0.010,"minor":0.010,"orient":0.000,"lat":0.011,"lon":0.012,"alt":0.020}',
    '{"class":"ATT","device":"/dev/pts/7",,"time":"2024-06-01T12:00:00.800Z""heading":90.010,"dip":0.010}',
    '{"class":"TPV","device":"/dev/pts/7","status":4,"mode":3,"time":"2024-06-01T12:00:00.900Z","lat":51,"lon":-1,"altHAE":7000}',
    '{"class":"ATT","device":"/dev/pts/7","heading":91.5}',
    '{"class":"ERROR","message":"unrecognized request"}',
    '{"class":"DEVICE","path":"/dev/pts/7","activated":0}',
]) + "\n"
put("fuzz_gpsd", "session.jsonl", gpsd)
put("fuzz_gpsd", "tpv.jsonl",
    '{"class":"TPV","device":"d","mode":2,"status":1,"time":"2024-06-01T12:00:01.000Z","lat":10.5,"lon":-20.25,"altMSL":100.0,"geoidSep":-30.5}\n')

# YAML: rigs, scenes, scenarios from the test data and assets.
for f in ("example.yaml", "opencv_calibrated.yaml", "bad_typo.yaml"):
    put("fuzz_rig", f, read("tests/data/rigs/" + f))
put("fuzz_rig", "paper_default.yaml", read("assets/rigs/paper_default.yaml"))
scenes = sorted(os.listdir(os.path.join(ROOT, "tests/data/scenes")))
for f in scenes[:8]:
    put("fuzz_scene", f, read("tests/data/scenes/" + f))
put("fuzz_scenario", "demo.yaml", read("assets/scenarios/demo.yaml"))
for f in ("bad_utc.yaml", "bad_outage.yaml", "bad_nested_unknown_key.yaml"):
    put("fuzz_scenario", f, read("tests/data/scenarios/" + f))

# Calibration files (first byte: '0' OpenCV, '1' ROS left/right, '2' Kalibr, '3' auto).
put("fuzz_calib", "opencv.yml", b"0" + read("tests/data/calib/opencv_stereo.yml"))
put("fuzz_calib", "ros.yaml", b"1" + read("tests/data/calib/ros_left.yaml") + b"\n---8<---\n" +
    read("tests/data/calib/ros_right.yaml"))
put("fuzz_calib", "kalibr.yaml", b"2" + read("tests/data/calib/kalibr_camchain.yaml"))
put("fuzz_calib", "auto.yaml", b"3" + read("tests/data/calib/kalibr_camchain.yaml"))

# Models (first byte: '0' .obj, '1' .gltf, '2' .glb).
for f, sel in (("textured.obj", b"0"), ("broken_index.obj", b"0"), ("box.gltf", b"1"),
               ("broken_accessor.gltf", b"1"), ("box.glb", b"2"), ("broken_truncated.glb", b"2")):
    put("fuzz_model", f, sel + read("tests/data/models/" + f))

# Blobs: mode (0 image, 1 mask, 2 difference; 0x80: compress the payload), u32 width, u32 height,
# format index, box (4 x i16), payload.
def codec(mode, w, h, fmt, payload, box=(0, 0, 0, 0)):
    return bytes([mode]) + struct.pack("<IIB4h", w, h, fmt, *box) + payload

def zstd(data):
    return subprocess.run(["zstd", "-q", "-c", "--content-size", "--check"], input=data,
                          stdout=subprocess.PIPE, check=True).stdout

img = bytes((x * 7 + y * 3) % 256 for y in range(8) for x in range(8))
put("fuzz_codec", "image_mono.bin", codec(0x80, 8, 8, 0, img))
put("fuzz_codec", "image_zstd.bin", codec(0, 8, 8, 0, zstd(img)))
put("fuzz_codec", "mask.bin", codec(0x81, 8, 8, 0, bytes(i % 4 for i in range(64))))
put("fuzz_codec", "difference.bin", codec(0x82, 7, 7, 1, bytes(range(48)), (2, 2, 6, 6)))
put("fuzz_codec", "big_row.bin", codec(0, 20000, 20000, 0, zstd(img)))

# Recording rows: per column a tag and its value (fuzz/fuzz_recording.cpp).
def col_null(): return b"\x00"
def col_i64(v): return b"\x01" + struct.pack("<q", v)
def col_i16(v): return b"\x02" + struct.pack("<h", v)
def col_f64(v): return b"\x03" + struct.pack("<d", v)
def col_name(i): return b"\x04" + bytes([i])  # 0..6 formats, 7..12 clocks, 13..17 stages
def col_text(s): return b"\x05" + bytes([len(s)]) + s
def col_zstd(b): return b"\x07" + struct.pack("<H", len(b)) + b

def frame_row(width, height, fmt, with_stats):
    r = col_i64(1) + col_i64(1400000000000000000) + col_i64(100)
    for cam in range(2):
        r += col_i64(1) + col_i64(1000 + cam) + col_name(7 + 3) + col_i64(5000) + col_i64(2000000)
        r += col_name(fmt) + col_i16(width) + col_i16(height)
    r += (col_f64(0.5) + col_f64(12) + col_f64(30) + col_f64(1) + col_f64(0) + col_f64(0) + col_f64(0)) * 3
    r += col_i64(1) + col_f64(0.02) + col_f64(0.1) + col_f64(0.5) + col_f64(0.0) + col_f64(4.0)
    # stats: 3 integers then 18 columns; NULL them all (no stats) or fill with small values.
    r += (col_i16(3) if with_stats else col_null()) * 21
    r += (col_i16(1) + col_i16(1) + col_i16(3) + col_i16(3)) * 2  # change boxes
    bpp = {0: 1, 1: 3, 2: 4}.get(fmt, 1)
    size = width * height * bpp
    r += col_zstd(bytes(i % 3 for i in range(width * height))) * 2  # masks
    r += col_zstd(bytes(range(2 * 2 * bpp))) * 2  # augmented boxes
    r += col_zstd(bytes((i * 5) % 256 for i in range(size))) * 2  # raw
    return r

nav = col_text(b"tanker.gps") + col_i64(1000) + col_name(11) + col_i64(1001) + col_text(b"$GNGGA,1*00")
drop = col_name(13) + col_text(b"left") + col_i16(3) + col_i64(10) + col_i64(20) + col_text(b"gap")
event = col_i64(5) + col_name(10) + col_text(b"start")
put("fuzz_recording", "mono.bin", frame_row(8, 6, 0, False) + nav + drop + event)
put("fuzz_recording", "rgb_stats.bin", frame_row(4, 4, 1, True) + nav + drop + event)
put("fuzz_recording", "bayer.bin", frame_row(6, 4, 3, False) + nav + drop + event)

# EuRoC (first byte: '0' camera data.csv, '1' imu0/data.csv).
put("fuzz_euroc", "camera.csv", "0#timestamp [ns],filename\r\n1403636579763555584,1403636579763555584.png\r\n"
    "1403636579813555456,1403636579813555456.png\r\n")
put("fuzz_euroc", "imu.csv",
    "1#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
    "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n1403636579758555392,-0.099,0.14,0.02,8.1,-1.9,-0.4\n"
    "1403636579763555584,-0.098,0.13,0.02,8.2,-1.9,-0.4\n1403636579768555520,-0.097,0.13,0.03,8.2,-1.9,-0.5\n")

# Source URIs.
for i, u in enumerate(["aravis://192.168.1.20?format=BayerRG8&fps=30&roi=0,0,1280,960", "v4l2:///dev/video2",
                       "replay:///data/flight 7/rec?rate=fast", "sim://demo?every=3",
                       "stereo:[tolerance_us=500,mode=trigger_id]//{aravis://127.0.0.1?fps=30&format=BayerRG8}{aravis://127.0.0.1:3957?fps=30}",
                       "stereo://{v4l2:///dev/video0}{v4l2:///dev/video1}"]):
    put("fuzz_source_uri", "uri%d.txt" % i, u)

# UBX: NAV-PVT, NAV-RELPOSNED (versions 0 and 1) and another message, with garbage between.
def ubx(cls, mid, payload):
    body = bytes([cls, mid]) + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for x in body:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes([a, b])


pvt = bytearray(92)
struct.pack_into("<IHBBBBBBIiBBBBiiiiIIiiiiiIIH", pvt, 0, 345600000, 2016, 12, 31, 23, 59, 42, 7, 25, -1200, 3,
                 0x83, 0, 17, -1177456789, 340123456, 1523456, 1500000, 14, 20, 150123, -2000, 300, 150136, 0, 30, 0,
                 123)
rel1 = bytearray(64)
struct.pack_into("<BBHIiiiiiBBBBbbbbIIIIIBBBBI", rel1, 0, 1, 0, 7, 345600000, 1234, -2, 567, 1372, 35712345, 0, 0,
                 0, 0, 56, -7, 0, 3, 100, 120, 250, 130, 50000, 0, 0, 0, 0, 0x12F)
rel0 = bytearray(40)
struct.pack_into("<BBHIiiibbbBIIII", rel0, 0, 0, 0, 0, 1000, -150, 20, 300, -5, 1, 2, 0, 300, 300, 600, 0x0C)
put("fuzz_ubx", "nav.ubx", ubx(1, 7, bytes(pvt)) + b"\x00\xb5" + ubx(1, 0x3C, bytes(rel1)) + ubx(1, 0x35, b"\x01\x02") +
    ubx(1, 0x3C, bytes(rel0)))
