"""PX4's FIFO topics (sensor_accel_fifo, sensor_gyro_fifo: every reading of each FIFO read, in counts times
scale) read reading for reading at their own times, chosen over the slower topics, and a FIFO that breaks
its definition named (simucal/io/ulog.py). Logs by tests/log_writers.py."""
import numpy as np
from click.testing import CliRunner
from cli_helpers import refused
from log_writers import write_ulog

from simucal.cli import main
from simucal.io.ulog import read_ulog, read_ulog_instances

G = 9.80665
ACC_SCALE, GYRO_SCALE = np.float32(G / 2048), np.float32(np.radians(2000) / 32768)  # ICM-42688-P's, +-16 g


def fifo_board(seconds=1.0, dt_us=500.0, seed=0, acc_id=2818058, gyro_id=2818058, t0_us=2.0e6):
    """A still board's FIFO readings every dt_us, read 6 to 10 at a time (each message's timestamp_sample
    the newest reading's); sensor_accel and sensor_gyro each message's mean with a temperature, as PX4
    publishes them. Returns (planted: t_us, acc, gyro per reading; fifo topics; sensor topics)."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(6, 11, int(seconds * 1e6 / dt_us / 8))
    t_us = t0_us + dt_us * np.arange(counts.sum())
    acc = np.round(np.array([0.1, -0.2, -G]) / ACC_SCALE + rng.normal(0, 4, (len(t_us), 3)))
    gyro = np.round(np.array([0.01, -0.005, 0.002]) / GYRO_SCALE + rng.normal(0, 3, (len(t_us), 3)))
    last = np.cumsum(counts) - 1
    temp = 30 + 5 * (t_us[last] - t0_us) / 1e6

    def fifo(values, scale, device_id):
        padded = np.zeros((len(counts), 32, 3))
        for m, (end, n) in enumerate(zip(last, counts)):
            padded[m, :n] = values[end - n + 1:end + 1]
        return {"t_us": t_us[last], "dt": dt_us, "scale": scale, "samples": counts, "device_id": device_id,
                **{axis: padded[:, :, j] for j, axis in enumerate("xyz")}}

    def mean(values, scale, device_id):
        means = np.add.reduceat(values, last - counts + 1) / counts[:, None] * scale
        return {"t_us": t_us[last], **{axis: means[:, j] for j, axis in enumerate("xyz")}, "temperature": temp,
                "device_id": device_id}
    planted = {"t_us": t_us, "acc": acc * ACC_SCALE, "gyro": gyro * GYRO_SCALE, "temp_at": (t_us[last], temp)}
    return (planted, (fifo(acc, ACC_SCALE, acc_id), fifo(gyro, GYRO_SCALE, gyro_id)),
            (mean(acc, ACC_SCALE, acc_id), mean(gyro, GYRO_SCALE, gyro_id)))


def test_the_fifo_is_read_reading_for_reading_and_wins_over_the_slower_topics(tmp_path):
    planted, (acc_fifo, gyro_fifo), (acc, gyro) = fifo_board()
    write_ulog(tmp_path / "f.ulg", acc, gyro, accel_fifo=acc_fifo, gyro_fifo=gyro_fifo)
    s = read_ulog(tmp_path / "f.ulg")
    log = s.log
    rates = {x["name"]: x["rate_hz"] for x in log["sources"]}
    assert log["source"] == "sensor_accel_fifo+sensor_gyro_fifo instance 0" and "highest rate" in log["why"]
    assert rates[log["source"]] == 2000.0 and 200 < rates["sensor_accel+sensor_gyro instance 0"] < 300
    assert "corrected" not in log and log["acc_device_id"] == log["gyro_device_id"] == 2818058
    # every reading a row at its own time (the first has no interval before it), in m/s^2 and rad/s
    np.testing.assert_array_equal(s.t_s, planted["t_us"][1:] * 1e-6)
    np.testing.assert_allclose(s.acc_mps2, planted["acc"][1:], rtol=1e-6)
    np.testing.assert_allclose(s.gyro_rads, planted["gyro"][1:], rtol=1e-6)
    # the temperature is sensor_accel's (the same device id) between its messages
    assert "sensor_accel instance 0" in log["temperature"]
    np.testing.assert_allclose(s.temp_c, np.interp(s.t_s * 1e6, *planted["temp_at"]), atol=1e-4)


def test_each_instance_is_its_own_fifo_by_device_id(tmp_path):
    """The FIFO topics' multi_ids follow their first publication: instance k is the sensor_accel
    instance of the same device id."""
    boards = [fifo_board(seed=k, acc_id=2818058 + 8 * k, gyro_id=2818058 + 8 * k) for k in (0, 1)]
    write_ulog(tmp_path / "two.ulg", [b[2][0] for b in boards], [b[2][1] for b in boards],
               accel_fifo=[b[1][0] for b in boards[::-1]], gyro_fifo=[b[1][1] for b in boards[::-1]])
    streams = read_ulog_instances(tmp_path / "two.ulg")
    for k, (s, (planted, *_)) in enumerate(zip(streams, boards)):
        assert s.log["source"] == f"sensor_accel_fifo+sensor_gyro_fifo instance {k}"
        assert s.log["acc_device_id"] == 2818058 + 8 * k
        np.testing.assert_allclose(s.gyro_rads, planted["gyro"][1:], rtol=1e-6)


def test_one_sensors_fifo_alone_is_no_source(tmp_path):
    _, (_, gyro_fifo), (acc, gyro) = fifo_board(seconds=0.3)
    write_ulog(tmp_path / "g.ulg", acc, gyro, gyro_fifo=gyro_fifo)
    s = read_ulog(tmp_path / "g.ulg")
    assert s.log["source"] == "sensor_accel+sensor_gyro instance 0" and len(s.log["sources"]) == 1
    write_ulog(tmp_path / "alone.ulg", None, None, gyro_fifo=gyro_fifo)
    r = CliRunner().invoke(main, ["import", "ulog", str(tmp_path / "alone.ulg"), "-o", str(tmp_path / "set"),
                                  "--latitude-deg", "47"])
    refused(r, "alone.ulg", "no topic holds both sensors", "sensor_gyro_fifo: instances 0")
    assert not (tmp_path / "set").exists()


def test_a_fifo_that_breaks_its_definition_is_named_and_left_out(tmp_path):
    _, (acc_fifo, gyro_fifo), (acc, gyro) = fifo_board(seconds=0.3)
    many = {**gyro_fifo, "samples": gyro_fifo["samples"].copy()}
    many["samples"][5] = 33
    write_ulog(tmp_path / "many.ulg", acc, gyro, accel_fifo=acc_fifo, gyro_fifo=many)
    s = read_ulog(tmp_path / "many.ulg")
    assert s.log["source"] == "sensor_accel+sensor_gyro instance 0"
    assert any("sensor_gyro_fifo instance 0, message 5 (of" in w and "samples 33, more than the 32" in w
               and "left out" in w for w in s.warnings), s.warnings
    # with nothing else to read: refused in one line naming the topic, nothing written
    no_dt = {**acc_fifo, "dt": np.r_[np.full(3, 500.0), 0.0, np.full(len(acc_fifo["t_us"]) - 4, 500.0)]}
    write_ulog(tmp_path / "dt.ulg", None, None, accel_fifo=no_dt, gyro_fifo=gyro_fifo)
    r = CliRunner().invoke(main, ["import", "ulog", str(tmp_path / "dt.ulg"), "-o", str(tmp_path / "set"),
                                  "--latitude-deg", "47"])
    refused(r, "dt.ulg", "sensor_accel_fifo instance 0, message 3", "dt 0 us, not a positive interval")
    assert not (tmp_path / "set").exists()


def test_an_older_logs_sensor_imu_fifo_holds_both_sensors_and_their_temperature(tmp_path):
    planted, (acc_fifo, gyro_fifo), _ = fifo_board(seconds=0.3)
    imu = {"t_us": acc_fifo["t_us"], "dt": 500.0, "samples": acc_fifo["samples"], "accel_scale": ACC_SCALE,
           "gyro_scale": GYRO_SCALE, "temperature": planted["temp_at"][1], "device_id": 2818058,
           **{f"{s}_{a}": f[a][:, :24] for s, f in (("accel", acc_fifo), ("gyro", gyro_fifo)) for a in "xyz"}}
    write_ulog(tmp_path / "imu.ulg", None, None, imu_fifo=imu)
    s = read_ulog(tmp_path / "imu.ulg")
    assert s.log["source"] == "sensor_imu_fifo instance 0" and "corrected" not in s.log
    np.testing.assert_array_equal(s.t_s, planted["t_us"][1:] * 1e-6)
    np.testing.assert_allclose(s.acc_mps2, planted["acc"][1:], rtol=1e-6)
    np.testing.assert_allclose(s.gyro_rads, planted["gyro"][1:], rtol=1e-6)
    # each reading its message's temperature
    message = np.repeat(np.arange(len(imu["t_us"])), imu["samples"])[1:]
    np.testing.assert_allclose(s.temp_c, imu["temperature"][message], atol=1e-4)
