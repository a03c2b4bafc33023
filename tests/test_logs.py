"""The logs MEMS users have (simucal/io/logs.py): a PX4 ULog, an ArduPilot DataFlash log and ROS 1
and ROS 2 bags, written here (tests/log_writers.py) from a still board warming up, read back as the logged
samples; every broken-file case refused in one line with nothing written."""
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from cli_helpers import refused
from log_writers import write_bag, write_dataflash, write_ulog

from simucal import io
from simucal.cli import main
from simucal.errors import CalibrationError

G = 9.80665


def still_board(seconds=20.0, acc_hz=200.0, gyro_hz=400.0, seed=0):
    """A still board (z down, FRD: the accelerometer reads -g on z), its temperature rising; each sensor at
    its own rate with a logger's jitter on its stamps. Columns as PX4 logs them: t_us, x y z, temperature."""
    rng = np.random.default_rng(seed)

    def topic(hz, truth, noise, device_id):
        t_s = np.arange(0.0, seconds, 1 / hz) + 1.5 + rng.uniform(0, 0.2 / hz, int(round(seconds * hz)))
        temp = 20.0 + 30.0 * (1 - np.exp(-t_s / 60.0))
        xyz = truth(temp) + rng.normal(0, noise, (len(t_s), 3))
        return {"t_us": np.round(t_s * 1e6), "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
                "temperature": temp, "device_id": device_id}
    acc = topic(acc_hz, lambda T: np.array([0.1, -0.2, -G]) + 1e-3 * np.outer(T - 35, [1, 2, -1]), 0.02, 1442826)
    gyro = topic(gyro_hz, lambda T: np.array([0.01, -0.005, 0.002]) + 1e-4 * np.outer(T - 35, [1, -1, 2]), 0.003,
                 2490378)
    return acc, gyro


def _import(*args):
    return CliRunner().invoke(main, ["import", *map(str, args)])


def test_a_ulog_becomes_a_stream_on_the_slower_sensors_clock(tmp_path):
    acc, gyro = still_board()
    write_ulog(tmp_path / "warm.ulg", acc, gyro)
    r = _import("ulog", tmp_path / "warm.ulg", "-o", tmp_path / "set", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "set")
    log = ms.meta["log"]
    assert (log["acc_device_id"] == 1442826 and log["gyro_device_id"] == 2490378
            and log["sensor_frame"].startswith("FRD"))
    # the first accel sample has no interval before it: left out, and counted
    assert "sensor_accel's samples" in log["clock"]["rows"] and log["clock"]["intervals_without_a_sample"][
        "rows_left_out"] == 1
    t_acc = acc["t_us"] * 1e-6
    # the rows are the accelerometer's samples (float32 as logged); the gyro each row's bin mean
    n = len(ms.samples["t_s"])
    assert n == len(t_acc) - 1  # the first accel sample has no interval before it
    np.testing.assert_allclose(ms.raw("acc"), np.column_stack([acc[k] for k in "xyz"])[1:], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(ms.samples["temp_c"], acc["temperature"][1:], atol=1e-5)
    t_g = gyro["t_us"] * 1e-6
    k = 100
    inside = (t_g > t_acc[k]) & (t_g <= t_acc[k + 1])
    np.testing.assert_allclose(ms.raw("gyro")[k], [gyro[a][inside].mean() for a in "xyz"], atol=1e-6)
    assert inside.sum() in (1, 2, 3)


def test_a_dataflash_log_keeps_its_imu_messages_and_device_ids(tmp_path):
    acc, gyro = still_board(gyro_hz=200.0)
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([gyro[k] for k in "xyz"]), "temperature": acc["temperature"]}
    write_dataflash(tmp_path / "warm.bin", imu, params={"INS_ACC_ID": 2753028, "INS_GYR_ID": 2752772,
                                                       "AHRS_ORIENTATION": 0})
    r = _import("dataflash", tmp_path / "warm.bin", "-o", tmp_path / "set", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "set")
    assert ms.meta["log"]["acc_device_id"] == 2753028 and ms.meta["log"]["gyro_device_id"] == 2752772
    np.testing.assert_allclose(ms.raw("gyro"), imu["gyro"], atol=1e-6)
    np.testing.assert_allclose(ms.samples["t_s"], (imu["t_us"] - imu["t_us"][0]) * 1e-6, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_gives_the_same_allan_terms_as_its_samples_in_csv(tmp_path, ros):
    """`simucal noise BAG` and `simucal noise SET` of the same samples written as samples.csv: the same terms."""
    rng = np.random.default_rng(ros)
    t = np.arange(0, 600.0, 0.01)
    acc = np.array([0.0, 0.0, G]) + rng.normal(0, 0.01, (len(t), 3))
    gyro = rng.normal(0, 1e-3, (len(t), 3)) + np.cumsum(rng.normal(0, 2e-6, (len(t), 3)), axis=0)
    bag = tmp_path / ("imu.bag" if ros == 1 else "imu_bag")
    write_bag(bag, t + 1000.0, acc, gyro, ros=ros)
    r = CliRunner().invoke(main, ["noise", str(bag), "-o", str(tmp_path / "bag.json")])
    assert r.exit_code == 0, r.output
    io.write_set(tmp_path / "csv", {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "latitude_deg": 0.0},
                 {"t_s": t, **{c: acc[:, j] for j, c in enumerate(("ax", "ay", "az"))},
                  **{c: gyro[:, j] for j, c in enumerate(("gx", "gy", "gz"))}})
    r = CliRunner().invoke(main, ["noise", str(tmp_path / "csv"), "-o", str(tmp_path / "csv.json")])
    assert r.exit_code == 0, r.output
    a, b = (json.loads((tmp_path / f).read_text()) for f in ("bag.json", "csv.json"))
    for s in ("acc", "gyro"):
        for axis in ("x", "y", "z"):
            for key in ("terms", "bounds", "adev"):
                ta, tb = a[s]["axes"][axis][key], b[s]["axes"][axis][key]
                if isinstance(ta, dict):
                    assert ta.keys() == tb.keys()
                    ta, tb = [ta[k] or 0.0 for k in ta], [tb[k] or 0.0 for k in ta]
                np.testing.assert_allclose(ta, tb, rtol=1e-6, err_msg=(s, axis, key))
            assert a[s]["axes"][axis]["terms"]["N"] > 0


def _refused_writing_nothing(tmp_path, *args_and_words):
    *args, words = args_and_words
    refused(_import(*args, "-o", tmp_path / "out", "--latitude-deg", 47.4), *words)
    assert not (tmp_path / "out").exists()


def test_broken_logs_are_refused_in_one_line_and_nothing_is_written(tmp_path):
    acc, gyro = still_board(seconds=2.0)
    write_ulog(tmp_path / "noacc.ulg", None, gyro)
    _refused_writing_nothing(tmp_path, "ulog", tmp_path / "noacc.ulg", ["noacc.ulg", "no topic holds both sensors",
                                                                       "sensor_gyro: instances 0"])
    write_ulog(tmp_path / "i1.ulg", acc, gyro, instance=1)
    _refused_writing_nothing(tmp_path, "ulog", tmp_path / "i1.ulg", "--instance", 0,
                             ["no IMU source of instance 0", "--instance 1"])
    (tmp_path / "not.ulg").write_bytes(b"hello, not a log\n" * 10)
    _refused_writing_nothing(tmp_path, "ulog", tmp_path / "not.ulg", ["not.ulg", "not a ULog"])
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([acc[k] for k in "xyz"]), "temperature": acc["temperature"]}
    write_dataflash(tmp_path / "i2.bin", imu, instance=2)
    _refused_writing_nothing(tmp_path, "dataflash", tmp_path / "i2.bin", "--instance", 0,
                             ["no IMU messages of instance 0", "--instance 2"])
    broken = bytearray((tmp_path / "i2.bin").read_bytes())
    at = broken.index(b"\xa3\x95\x41", len(broken) // 2)  # an IMU message's head, mid-file
    broken[at:at + 2] = b"\x00\x00"
    (tmp_path / "broken.bin").write_bytes(bytes(broken))
    _refused_writing_nothing(tmp_path, "dataflash", tmp_path / "broken.bin", ["broken.bin", "broken at byte",
                                                                              "bytes follow"])
    write_dataflash(tmp_path / "none.bin", None)
    _refused_writing_nothing(tmp_path, "dataflash", tmp_path / "none.bin", ["no IMU messages"])
    t = np.arange(200) * 0.005
    write_bag(tmp_path / "temp.bag", t, None, None, topic="/imu/temperature", msgtype="sensor_msgs/msg/Temperature")
    _refused_writing_nothing(tmp_path, "rosbag", tmp_path / "temp.bag", ["no sensor_msgs/Imu topic",
                                                                       "/imu/temperature"])
    _refused_writing_nothing(tmp_path, "rosbag", tmp_path / "temp.bag", "--topic", "/imu/temperature",
                             ["is sensor_msgs/msg/Temperature, not sensor_msgs/Imu"])
    write_bag(tmp_path / "ok.bag", t, np.zeros((200, 3)), np.zeros((200, 3)))
    _refused_writing_nothing(tmp_path, "rosbag", tmp_path / "ok.bag", "--topic", "/camera",
                             ["no topic /camera in the bag", "/imu"])
    (tmp_path / "cut.bag").write_bytes((tmp_path / "ok.bag").read_bytes()[:-300])
    _refused_writing_nothing(tmp_path, "rosbag", tmp_path / "cut.bag", ["cut.bag"])


@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_read_as_records_equals_its_messages(tmp_path, ros):
    """io/logs._imu_rows reads a topic whose messages share one length as one numpy record array at the fields'
    offsets (ROS 1 packed, ROS 2 CDR-aligned): the rows equal the messages to the bit, with one frame_id
    and, message by message, where the frame_id's length changes (and the stamps where a header's is 0)."""
    from simucal.io.logs import read_rosbag
    rng = np.random.default_rng(ros)
    t = 1000.0 + np.arange(300) * 0.005
    acc, gyro = rng.normal(0, 1, (300, 3)), rng.normal(0, 1, (300, 3))
    for name, frames in (("one", None), ("mixed", lambda k: "imu" if k % 2 else "imu_link_x"), ("odd", lambda k: "i")):
        bag = tmp_path / (f"{name}.bag" if ros == 1 else name)
        write_bag(bag, t, acc, gyro, ros=ros, frame_id=frames)
        s = read_rosbag(bag)
        np.testing.assert_array_equal(s.acc_mps2, acc, err_msg=name)
        np.testing.assert_array_equal(s.gyro_rads, gyro, err_msg=name)
        np.testing.assert_allclose(s.t_s, t, rtol=0, atol=1e-9, err_msg=name)


PYULOG_DATA = Path(__file__).parent / "data" / "pyulog"  # real logs, pyulog's test data (its README)


@pytest.mark.parametrize("name", ["sample_log_small.ulg", "sample_appended_multiple.ulg"])
def test_a_real_ulog_of_the_default_profile_imports_sensor_combined_sample_for_sample(tmp_path, name):
    """PX4's default profile logs the full-rate IMU as sensor_combined only (sensor_accel at 1 Hz, if at all):
    the import takes it, names it and every other source with its rate, and its rows are pyulog's read of
    that topic, message for message."""
    import pyulog
    r = _import("ulog", PYULOG_DATA / name, "-o", tmp_path / "set", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "set")
    log = ms.meta["log"]
    assert log["source"] == "sensor_combined" and log["why"]
    d = pyulog.ULog(str(PYULOG_DATA / name), ["sensor_combined"]).get_dataset("sensor_combined").data
    valid = d["accelerometer_timestamp_relative"] != 2147483647
    assert valid.all() and len(ms.samples["t_s"]) == len(d["timestamp"])
    np.testing.assert_allclose(ms.samples["t_s"], (d["timestamp"] - d["timestamp"][0]) * 1e-6, rtol=0, atol=1e-9)
    for sensor, field in (("acc", "accelerometer_m_s2"), ("gyro", "gyro_rad")):
        logged = np.column_stack([d[f"{field}[{j}]"] for j in range(3)]).astype(float)
        np.testing.assert_allclose(ms.raw(sensor), logged, rtol=1e-7, atol=0)  # float32 as logged, through CSV
    rates = {s["name"]: s["rate_hz"] for s in log["sources"]}
    assert rates["sensor_combined"] > 150
    if name == "sample_log_small.ulg":  # its sensor_accel at 1 Hz and vehicle_imu at 2 Hz lose to it
        assert rates["sensor_accel+sensor_gyro instance 0"] < 2 and rates["vehicle_imu instance 1"] < 3
        assert log["acc_device_id"] == log["gyro_device_id"] == 2424842  # sensor_selection's
        assert "interpolated" in log["temperature"] and "temp_c" in ms.samples


def test_a_real_ulog_gives_its_latitude_and_a_low_rate_source_is_named(tmp_path):
    """The latitude from the log's GPS fixes where none is given; an instance asked for whose only source is
    1 Hz is read and said to be."""
    r = _import("ulog", PYULOG_DATA / "sample_log_small.ulg", "-o", tmp_path / "set", "--instance", 1)
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "set")
    assert abs(ms.meta["latitude_deg"] - 63.417) < 1e-3 and "GPS" in ms.meta["log"]["latitude"]
    assert ms.meta["log"]["source"] == "vehicle_imu instance 1"  # 2 Hz beats sensor_accel's 1 Hz
    assert "under 10 Hz" in r.output and "full rate" in r.output
    assert any("under 10 Hz" in w for w in ms.meta["warnings"])


def test_a_log_cut_inside_its_last_message_keeps_every_whole_message_and_names_the_cut(tmp_path):
    acc, gyro = still_board(seconds=2.0, gyro_hz=200.0)
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([gyro[k] for k in "xyz"]), "temperature": acc["temperature"]}
    write_dataflash(tmp_path / "cut.bin", imu, truncate_bytes=5)
    r = _import("dataflash", tmp_path / "cut.bin", "-o", tmp_path / "df", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    assert "cut inside its last message" in r.output and "cut.bin" in r.output
    np.testing.assert_allclose(io.read_set(tmp_path / "df").raw("gyro"), imu["gyro"][:-1], atol=1e-6)
    write_ulog(tmp_path / "cut.ulg", acc, gyro, truncate_bytes=7)
    r = _import("ulog", tmp_path / "cut.ulg", "-o", tmp_path / "ulg", "--latitude-deg", 47.4)
    assert r.exit_code == 0 and "cut inside its last message" in r.output, r.output
    write_ulog(tmp_path / "whole.ulg", acc, gyro)
    assert _import("ulog", tmp_path / "whole.ulg", "-o", tmp_path / "whole", "--latitude-deg", 47.4).exit_code == 0
    cut, whole = (io.read_set(tmp_path / f).raw("acc") for f in ("ulg", "whole"))
    assert len(whole) - 1 <= len(cut) < len(whole)  # the last message lost, whichever sensor's it was
    np.testing.assert_array_equal(cut[:-1], whole[:len(cut) - 1])


def test_an_older_dataflash_logs_imu2_as_instance_1_with_its_device_ids(tmp_path):
    acc, gyro = still_board(seconds=2.0, gyro_hz=200.0)
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([gyro[k] for k in "xyz"]), "temperature": acc["temperature"]}
    second = {**imu, "acc": imu["acc"] + 0.05}
    write_dataflash(tmp_path / "old.bin", [imu, second], numbered=True,
                    params={"INS_ACC_ID": 1, "INS_GYR_ID": 2, "INS_ACC2_ID": 11, "INS_GYR2_ID": 12})
    r = _import("dataflash", tmp_path / "old.bin", "-o", tmp_path / "set", "--latitude-deg", 47.4, "--instance", 1)
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "set")
    assert ms.meta["log"]["messages"] == "IMU2" and ms.meta["log"]["instances"] == [0, 1]
    assert (ms.meta["log"]["acc_device_id"], ms.meta["log"]["gyro_device_id"]) == (11, 12)
    np.testing.assert_allclose(ms.raw("acc"), second["acc"], atol=1e-5)


def test_broken_log_contents_are_refused_or_named_in_one_line(tmp_path):
    """NaN samples and sensors that never overlap refused (nothing written); a ULog renamed .bin refused in
    one line (pymavlink's byte-by-byte complaints kept off the screen); a gap and a magnitude far from g named."""
    acc, gyro = still_board(seconds=4.0, gyro_hz=200.0)
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([gyro[k] for k in "xyz"]), "temperature": acc["temperature"]}
    nan = {**imu, "gyro": imu["gyro"].copy()}
    nan["gyro"][300:305, 1] = np.nan
    write_dataflash(tmp_path / "nan.bin", nan)
    _refused_writing_nothing(tmp_path, "dataflash", tmp_path / "nan.bin", ["nan.bin", "5 gyro samples are NaN",
                                                                           "row 301"])
    later = {k: (v + 10e6 if k == "t_us" else v) for k, v in gyro.items()}
    write_ulog(tmp_path / "apart.ulg", acc, later)
    _refused_writing_nothing(tmp_path, "ulog", tmp_path / "apart.ulg", ["apart.ulg", "never overlap"])
    (tmp_path / "ulog.bin").write_bytes((PYULOG_DATA / "sample_log_small.ulg").read_bytes())
    r = _import("dataflash", tmp_path / "ulog.bin", "-o", tmp_path / "out", "--latitude-deg", 47.4)
    assert r.exit_code != 0 and len(r.output.strip().splitlines()) == 1, r.output
    assert "not a DataFlash log" in r.output and "import ulog" in r.output and not (tmp_path / "out").exists()
    keep = (acc["t_us"] < 2.0e6) | (acc["t_us"] > 3.0e6)
    gappy = {**imu, **{k: imu[k][keep] for k in ("t_us", "acc", "gyro", "temperature")}}
    gappy["acc"] = gappy["acc"] * 27.0  # a "still" unit reading 265 m/s^2
    write_dataflash(tmp_path / "gap.bin", gappy)
    r = _import("dataflash", tmp_path / "gap.bin", "-o", tmp_path / "gap", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    assert "1 gap in t_s" in r.output and "samples missing" in r.output and "not near g" in r.output
    gaps = io.read_set(tmp_path / "gap").meta["log"]["gaps"]
    assert len(gaps) == 1 and abs(gaps[0]["length_s"] - 1.0) < 0.02


def test_topic_on_a_measurement_set_names_the_set_and_the_option(tmp_path):
    io.write_set(tmp_path / "set", {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "latitude_deg": 0.0},
                 {"t_s": np.arange(10) * 0.01, **{c: np.zeros(10) for c in ("ax", "ay", "gx", "gy", "gz")},
                  "az": np.full(10, G)})
    r = CliRunner().invoke(main, ["noise", str(tmp_path / "set"), "--topic", "/imu", "-o", str(tmp_path / "n.json")])
    refused(r, "a measurement set", "--topic")


def test_px4_parameters_are_never_fitted_on_data_px4_has_already_calibrated(tmp_path):
    """sensor_combined is VehicleIMU's output, PX4's calibration (and thermal compensation) in it: the import says
    so, and --px4 from such a set is refused; a DataFlash log ending in padding keeps its messages; a temperature
    logged NaN at first drops the column, said."""
    r = _import("ulog", PYULOG_DATA / "sample_log_small.ulg", "-o", tmp_path / "set", "--latitude-deg", 47.4)
    assert r.exit_code == 0, r.output
    assert "calibration already applied" in io.read_set(tmp_path / "set").meta["log"]["corrected"]
    import simucal
    from simucal.io.autopilot import texts
    acc, gyro = still_board(seconds=120.0, acc_hz=50.0, gyro_hz=100.0)
    write_ulog(tmp_path / "w.ulg", acc, gyro)
    assert _import("ulog", tmp_path / "w.ulg", "-o", tmp_path / "raw", "--latitude-deg", 47.4).exit_code == 0
    cal = simucal.calibrate(tmp_path / "raw", thermal=True)
    meta = io.read_set(tmp_path / "raw").meta
    assert texts([(cal, meta)], px4="tc.params")  # the raw topics: written
    meta["log"] = io.read_set(tmp_path / "set").meta["log"]  # as if the warm-up were sensor_combined's
    with pytest.raises(CalibrationError, match="sensor_combined.*raw sensor_accel/sensor_gyro"):
        texts([(cal, meta)], px4="tc.params")
    acc, gyro = still_board(seconds=2.0, gyro_hz=200.0)
    temp = acc["temperature"].copy()
    temp[:10] = np.nan
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([gyro[k] for k in "xyz"]), "temperature": temp}
    write_dataflash(tmp_path / "pad.bin", imu)
    (tmp_path / "pad.bin").write_bytes((tmp_path / "pad.bin").read_bytes() + bytes(512))
    r = _import("dataflash", tmp_path / "pad.bin", "-o", tmp_path / "pad", "--latitude-deg", 47.4)
    assert r.exit_code == 0 and "the last 512 bytes are left out" in r.output, r.output
    assert "10 of 400 temperature samples are NaN" in r.output
    pad = io.read_set(tmp_path / "pad")
    assert len(pad.samples["t_s"]) == 400 and "temp_c" not in pad.samples
