#!/usr/bin/env python3
"""Writes the seed inputs of the `can_rx` and `wav` fuzz targets that no
repository file provides (python3, standard library only):

- can_rx/*.bin: drives in the target's record format (fuzz_targets/can_rx.rs)
  built from the messages of config/inverter.dbc: WheelSpeeds and
  MotorStatus every 1 ms, VehicleSpeed and DriverDemand every 10 ms, a
  loop cycle every 1 ms; one with faults (bad CRCs, wrong DLCs, repeated
  and skipped counters, unknown ids, a sensor gap past the timeout).
- wav/*.wav: 10 ms files in each layout the decoder takes (8/16/24/32-bit
  PCM, 32-bit float, mono and stereo, WAVE_FORMAT_EXTENSIBLE).

Run from this directory: `python3 make_seeds.py`. The outputs are checked in.
"""
import math
import os
import struct

# ------------------------------------------------------------------ CAN ----
# message index in the target: 0 TorqueCommand, 1 MotorStatus,
# 2 WheelSpeeds, 3 VehicleSpeed, 4 DriverDemand (ids 0x100..0x140)
FIX_CRC, FIX_CTR, CYCLE, NO_FRAME = 1, 2, 4, 8


def i16(v, scale):
    return struct.pack("<h", max(-32768, min(32767, round(v / scale))))


def payload(flags_byte1, sig16_a=b"\0\0", sig16_b=b"\0\0", b6=0, b7=0):
    # data[0] = CRC and the low nibble of data[1] = counter: the target fills them
    return bytes([0, flags_byte1]) + sig16_a + sig16_b + bytes([b6, b7])


def rec(flags, msg, dt, data, dlc=8):
    assert len(data) == 8
    return bytes([flags, msg, dlc, dt]) + data


def wheel(od, oref):  # DrivenValid (bit 12), RefValid (bit 13)
    return payload(0x30, i16(od, 0.01), i16(oref, 0.01))


def motor(torque, speed):  # Ready (bit 12)
    return payload(0x10, i16(torque, 0.1), i16(speed, 0.01))


def vspeed(v):  # Valid (bit 12)
    return payload(0x10, i16(v, 0.01), i16(0.0, 0.001))


def demand(torque, pedal):  # TcsEnable (bit 13)
    return payload(0x20, i16(torque, 0.1), bytes([round(pedal / 0.5), 0]))


def drive(setup, ms, slip, torque, faults=False):
    out = bytearray([setup])
    r = 0.3
    for t in range(ms):
        v = 3.0 + 0.02 * t
        oref = v / r
        od = oref * (1.0 + slip)
        f = FIX_CRC | FIX_CTR
        out += rec(f, 2, 10, wheel(od, oref))
        out += rec(f, 1, 0, motor(min(torque, 30 + t), od))
        if t % 10 == 0:
            out += rec(f, 3, 0, vspeed(v))
            out += rec(f, 4, 0, demand(torque, 60.0))
        if faults and t % 7 == 3:
            out += rec(FIX_CTR, 2, 0, wheel(od, oref))  # CRC not fixed: wrong
            out += rec(f, 1, 0, motor(0, 0), dlc=5)  # wrong length
            out += rec(FIX_CRC, 1, 0, motor(0, 0))  # counter repeated (0)
            out += rec(f, 0x41, 0, bytes(8))  # unknown id
        if faults and t == 60:
            out += rec(NO_FRAME, 2, 200, bytes(8))  # 20 ms without sensors
        out += rec(CYCLE | NO_FRAME, 0, 0, bytes(8))
    return bytes(out)


def write(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as f:
        f.write(data)


write("can_rx/mfc_arte.bin", drive(0x80, 120, 0.08, 300.0))
write("can_rx/src.bin", drive(0x01, 120, 0.02, 150.0))
write("can_rx/mtte_arte.bin", drive(0x82, 120, 0.15, 300.0))
write("can_rx/faults.bin", drive(0x80, 100, 0.05, 200.0, faults=True))

# ------------------------------------------------------------------ WAV ----


def wav(path, rate, channels, bits, fmt="int", extensible=False, ms=10):
    n = rate * ms // 1000
    frames = bytearray()
    for i in range(n):
        x = 0.5 * math.sin(2 * math.pi * 440.0 * i / rate)
        for c in range(channels):
            y = x if c == 0 else -x
            if fmt == "float":
                frames += struct.pack("<f", y)
            elif bits == 8:
                frames += bytes([round(128 + 127 * y)])
            else:
                v = round(y * (2 ** (bits - 1) - 1))
                frames += v.to_bytes(bits // 8, "little", signed=True)
    block = channels * bits // 8
    tag = 3 if fmt == "float" else 1
    if extensible:
        # KSDATAFORMAT_SUBTYPE_PCM / _IEEE_FLOAT
        guid = struct.pack("<I", tag) + bytes.fromhex("00001000800000aa00389b71")
        fmt_body = struct.pack("<HHIIHH", 0xFFFE, channels, rate, rate * block, block, bits)
        fmt_body += struct.pack("<HHI", 22, bits, (1 << channels) - 1) + guid
    else:
        fmt_body = struct.pack("<HHIIHH", tag, channels, rate, rate * block, block, bits)
    body = b"WAVE" + b"fmt " + struct.pack("<I", len(fmt_body)) + fmt_body
    body += b"data" + struct.pack("<I", len(frames)) + bytes(frames)
    write(path, b"RIFF" + struct.pack("<I", len(body)) + body)


wav("wav/mono16_44k1.wav", 44100, 1, 16)
wav("wav/stereo24_48k.wav", 48000, 2, 24)
wav("wav/mono_f32_16k.wav", 16000, 1, 32, fmt="float")
wav("wav/mono8_8k.wav", 8000, 1, 8)
wav("wav/ext_s32_stereo_22k.wav", 22050, 2, 32, extensible=True)
