"""Settings: packaged defaults, a user TOML file over them, flags over that; mistakes named."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_voice.settings import SettingsError, load_settings


def test_defaults_are_sensible() -> None:
    s = load_settings()
    assert (s.horizontal_speed_m_s, s.vertical_speed_m_s, s.floor_m) == (0.5, 0.3, 0.5)
    assert s.setpoint_hz == 10 and s.link_lost_s == 2 and (s.gcs_system_id, s.gcs_component_id) == (255, 231)


def test_user_file_then_flags(tmp_path: Path) -> None:
    path = tmp_path / "mine.toml"
    path.write_text("[safety]\nceiling_m = 4.0\n[motion]\nhorizontal_speed_m_s = 1\n")
    s = load_settings(path, horizontal_speed_m_s=0.8, floor_m=None)
    assert (s.ceiling_m, s.horizontal_speed_m_s, s.floor_m) == (4.0, 0.8, 0.5)


@pytest.mark.parametrize(("text", "needle"), [
    ("[safety]\nceling_m = 4\n", "unknown setting 'celing_m'"),
    ("[safety]\nceiling_m = 'high'\n", "must be a number"),
    ("[safety]\nceiling_m = nan\n", "finite"),
    ("[safety]\nfloor_m = 20\n", "below ceiling_m"),
    ("[link]\ngcs_system_id = 1.5\n", "whole number"),
    ("ceiling_m = [", "invalid TOML"),
    ("[motion]\nhorizontal_speed_m_s = 1e9\n", "horizontal_speed_m_s 1e+09: must be within 0.05-2 m/s"),
    ("[motion]\ntakeoff_altitude_m = 0\n", "takeoff_altitude_m 0: must be within"),
    ("[motion]\ntakeoff_altitude_m = 12\n", "must not be above ceiling_m"),
    ("[safety]\nfence_radius_m = -1\n", "fence_radius_m -1: must be within 1-500 m"),
    ("[link]\nsetpoint_hz = 1\n", "setpoint_hz 1: must be within"),
    ("[limits]\nhorizontal_speed_m_s = [0, 100]\n", "[limits] can only be changed in the packaged settings"),
])
def test_mistakes_are_one_line_errors(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SettingsError) as info:
        load_settings(path)
    assert needle in str(info.value) and str(info.value).count(str(path)) == 1


def test_missing_file() -> None:
    with pytest.raises(SettingsError, match="not found"):
        load_settings("/nonexistent/settings.toml")


def test_every_packaged_default_is_within_its_limit_and_limits_name_real_settings() -> None:
    from dataclasses import fields

    from gcs_voice.settings import Settings, setting_limits

    s, limits = load_settings(), setting_limits()
    assert {"horizontal_speed_m_s", "vertical_speed_m_s", "floor_m", "ceiling_m", "fence_radius_m",
            "takeoff_altitude_m"} <= set(limits)
    for f in fields(Settings):
        if f.name in limits:
            assert limits[f.name].low <= getattr(s, f.name) <= limits[f.name].high, f.name


def test_overrides_are_named_as_the_user_wrote_them() -> None:
    with pytest.raises(SettingsError, match=r"^--fence -1: must be within 1-500 m$"):
        load_settings(names={"fence_radius_m": "--fence"}, fence_radius_m=-1)
    with pytest.raises(SettingsError, match=r"^--floor \(3\) must be below --ceiling \(2\)$"):
        load_settings(names={"floor_m": "--floor", "ceiling_m": "--ceiling"}, floor_m=3, ceiling_m=2)
