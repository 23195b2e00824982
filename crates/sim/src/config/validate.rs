//! Loading a [`SimConfig`] from TOML and validating every field a simulation depends on, section
//! by section; an error names the key.
//!
//! Separate because validation is long (one rule per key) and is read apart from the format.

use super::checks::{bounded, finite, invalid, non_negative, positive, tilt, unique};
use super::{AirBetweenReadings, FleetConfig, SimConfig};
use crate::SimError;

impl SimConfig {
    /// Parse and validate a TOML configuration.
    pub fn from_toml_str(text: &str) -> Result<Self, SimError> {
        let cfg: Self = toml::from_str(text)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Read, parse and validate a TOML file.
    #[cfg(test)]
    pub(crate) fn load(path: &std::path::Path) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path).map_err(|source| SimError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text)
    }

    /// The fleet generator in force when `bars` is empty: the given one or the default.
    pub(crate) fn fleet_or_default(&self) -> FleetConfig {
        self.fleet.clone().unwrap_or_default()
    }

    /// Check every field a simulation depends on; the error names the key.
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        positive("duration_days", self.duration_days)?;
        positive("sample_s", self.sample_s)?;
        positive("max_internal_step_s", self.max_internal_step_s)?;
        non_negative("noise_um", self.noise_um)?;
        positive("resolution_nm", self.resolution_nm)?;
        finite("reference_temperature_c", self.reference_temperature_c)?;
        if self.duration_days > 3660.0 {
            return Err(invalid("duration_days", "longer than ten years"));
        }
        if self.sample_s < 1e-3 {
            return Err(invalid("sample_s", "below a millisecond"));
        }
        self.validate_plate()?;
        self.validate_bars()?;
        self.validate_room()?;
        self.validate_schedule()?;
        self.validate_phases()?;
        self.validate_geometry()?;
        self.validate_mismatch()?;
        self.validate_generation()?;
        self.validate_effects()
    }

    /// The internal integration step (seconds) the grid will use: `sample_s` divided into the
    /// fewest steps of at most `max_internal_step_s` ([`super::Grid`]).
    pub(crate) fn internal_step_s(&self) -> f64 {
        let steps = (self.sample_s / self.max_internal_step_s).ceil().max(1.0);
        (self.sample_s * 1e9).round() * 1e-9 / steps
    }

    fn validate_generation(&self) -> Result<(), SimError> {
        let g = &self.generation;
        non_negative("generation.prehistory_hours", g.prehistory_hours)?;
        if g.prehistory_hours > 24.0 * 366.0 {
            return Err(invalid("generation.prehistory_hours", "longer than a year"));
        }
        if g.air_between_readings != AirBetweenReadings::Continuous {
            // The air is rebuilt from its values at the reading times on the internal grid:
            // the readings must fall on grid points.
            let ratio = self.room.temperature_sample_s / self.internal_step_s();
            if (ratio - ratio.round()).abs() > 1e-6 || ratio.round() < 1.0 {
                return Err(invalid(
                    "generation.air_between_readings",
                    "needs room.temperature_sample_s to be a multiple of the internal step \
                     (sample_s divided into steps of at most max_internal_step_s)",
                ));
            }
        }
        Ok(())
    }

    fn validate_plate(&self) -> Result<(), SimError> {
        let p = &self.plate;
        finite("plate.cte_ppm_per_k", p.cte_ppm_per_k)?;
        tilt("plate.tilt_deg", p.tilt_deg)?;
        positive("plate.thermal_tau_s", p.thermal_tau_s)?;
        if p.length.is_empty() {
            return Err(invalid("plate.length", "no plate length"));
        }
        for (i, l) in p.length.iter().enumerate() {
            positive(&format!("plate.length[{i}].mm"), l.mm)?;
            non_negative(&format!("plate.length[{i}].u_um"), l.u_um)?;
        }
        unique("plate.length.id", p.length.iter().map(|l| l.id.as_str()))
    }

    fn validate_bars(&self) -> Result<(), SimError> {
        if !self.bars.is_empty() && self.fleet.is_some() {
            return Err(invalid("fleet", "give either `bars` or `fleet`, not both"));
        }
        let min_mm = self
            .plate
            .length
            .iter()
            .map(|l| l.mm)
            .fold(f64::INFINITY, f64::min);
        for (i, b) in self.bars.iter().enumerate() {
            let key = |f: &str| format!("bars[{i}].{f}");
            if b.id.is_empty() {
                return Err(invalid(&key("id"), "empty"));
            }
            positive(&key("fixed_length_mm"), b.fixed_length_mm)?;
            if b.fixed_length_mm >= min_mm {
                return Err(invalid(
                    &key("fixed_length_mm"),
                    "not below the shortest plate length",
                ));
            }
            finite(&key("alpha_ppm_per_k"), b.alpha_ppm_per_k)?;
            finite(&key("beta_ppm_per_k"), b.beta_ppm_per_k)?;
            positive(&key("tau_r_s"), b.tau_r_s)?;
            positive(&key("tau_s_s"), b.tau_s_s)?;
        }
        unique("bars.id", self.bars.iter().map(|b| b.id.as_str()))?;
        if self.bars.is_empty() {
            self.validate_fleet(min_mm)?;
        }
        Ok(())
    }

    fn validate_fleet(&self, min_mm: f64) -> Result<(), SimError> {
        let f = self.fleet_or_default();
        if f.n_bars == 0 || f.n_bars > 999 {
            return Err(invalid("fleet.n_bars", "must be 1..=999"));
        }
        positive("fleet.fixed_length_mm", f.fixed_length_mm)?;
        non_negative("fleet.fixed_length_sd_mm", f.fixed_length_sd_mm)?;
        if f.fixed_length_mm + 5.0 * f.fixed_length_sd_mm >= min_mm {
            return Err(invalid(
                "fleet.fixed_length_mm",
                "too close to the shortest plate length",
            ));
        }
        finite("fleet.alpha_ppm_per_k", f.alpha_ppm_per_k)?;
        non_negative("fleet.alpha_sd_ppm_per_k", f.alpha_sd_ppm_per_k)?;
        finite("fleet.beta_ppm_per_k", f.beta_ppm_per_k)?;
        non_negative("fleet.beta_sd_ppm_per_k", f.beta_sd_ppm_per_k)?;
        positive("fleet.tau_r_s", f.tau_r_s)?;
        positive("fleet.tau_s_s", f.tau_s_s)?;
        non_negative("fleet.tau_rel_sd", f.tau_rel_sd)
    }

    fn validate_room(&self) -> Result<(), SimError> {
        let r = &self.room;
        finite("room.mean_c", r.mean_c)?;
        for (k, v) in [
            ("room.daily_amplitude_k", r.daily_amplitude_k),
            ("room.ac_amplitude_k", r.ac_amplitude_k),
            ("room.wander_k", r.wander_k),
            ("room.door_rate_per_day", r.door_rate_per_day),
            ("room.door_amplitude_k", r.door_amplitude_k),
            ("room.setpoint_step_k", r.setpoint_step_k),
            ("room.gradient_daily_k", r.gradient_daily_k),
            ("room.gradient_ac_k", r.gradient_ac_k),
            ("room.gradient_wander_k", r.gradient_wander_k),
            ("room.sensor_noise_k", r.sensor_noise_k),
        ] {
            non_negative(k, v)?;
        }
        finite("room.daily_peak_hour", r.daily_peak_hour)?;
        finite("room.drift_k_per_day", r.drift_k_per_day)?;
        finite("room.gradient_k", r.gradient_k)?;
        positive("room.ac_period_s", r.ac_period_s)?;
        positive("room.door_rise_s", r.door_rise_s)?;
        positive("room.door_decay_s", r.door_decay_s)?;
        positive("room.setpoint_half_period_s", r.setpoint_half_period_s)?;
        positive("room.setpoint_settle_s", r.setpoint_settle_s)?;
        if r.door_decay_s <= r.door_rise_s {
            return Err(invalid("room.door_decay_s", "must exceed room.door_rise_s"));
        }
        if r.door_rate_per_day > 1440.0 {
            return Err(invalid("room.door_rate_per_day", "more than one a minute"));
        }
        if r.temperature_sample_s.is_nan() || r.temperature_sample_s < 0.1 {
            return Err(invalid(
                "room.temperature_sample_s",
                "must be at least 0.1 s",
            ));
        }
        Ok(())
    }

    fn validate_schedule(&self) -> Result<(), SimError> {
        let s = &self.schedule;
        positive("schedule.mount_days", s.mount_days)?;
        non_negative("schedule.gap_minutes", s.gap_minutes)?;
        non_negative("schedule.stagger_minutes", s.stagger_minutes)?;
        non_negative("schedule.handling_offset_mm", s.handling_offset_mm)?;
        if s.mount_days * 86400.0 < 60.0 {
            return Err(invalid("schedule.mount_days", "shorter than a minute"));
        }
        for (i, id) in s.lengths.iter().enumerate() {
            if !self.plate.length.iter().any(|l| &l.id == id) {
                return Err(invalid(
                    &format!("schedule.lengths[{i}]"),
                    "no such plate length",
                ));
            }
        }
        unique("schedule.lengths", s.lengths.iter().map(String::as_str))?;
        for (i, r) in s.reference.iter().enumerate() {
            if !self.plate.length.iter().any(|l| l.id == r.length) {
                return Err(invalid(
                    &format!("schedule.reference[{i}].length"),
                    "no such plate length",
                ));
            }
        }
        unique(
            "schedule.reference.bar",
            s.reference.iter().map(|r| r.bar.as_str()),
        )
    }

    /// The calibration phase and the working layout.
    fn validate_phases(&self) -> Result<(), SimError> {
        let s = &self.schedule;
        if let Some(c) = &s.calibration {
            if c.tilts_deg.is_empty() {
                return Err(invalid("schedule.calibration.tilts_deg", "no tilt"));
            }
            for (i, &t) in c.tilts_deg.iter().enumerate() {
                tilt(&format!("schedule.calibration.tilts_deg[{i}]"), t)?;
            }
            positive("schedule.calibration.mount_hours", c.mount_hours)?;
            if c.mount_hours < 1.0 / 60.0 {
                return Err(invalid(
                    "schedule.calibration.mount_hours",
                    "shorter than a minute",
                ));
            }
            let rounds = (c.tilts_deg.len() * self.plate.length.len()) as f64;
            let phase_s = rounds * (c.mount_hours * 3600.0 + s.gap_minutes.max(1.0 / 60.0) * 60.0);
            if phase_s >= self.duration_days * 86400.0 {
                return Err(invalid(
                    "schedule.calibration",
                    "the calibration phase does not end before the campaign",
                ));
            }
        }
        let Some(w) = &s.working else { return Ok(()) };
        if !self.plate.length.iter().any(|l| l.id == w.length) {
            return Err(invalid("schedule.working.length", "no such plate length"));
        }
        if w.purpose == dbbcal_core::campaign::Purpose::Reference {
            return Err(invalid(
                "schedule.working.purpose",
                "must be check or calibration (references go in schedule.reference)",
            ));
        }
        let Some(d) = &w.device else { return Ok(()) };
        if d.id.trim().is_empty() {
            return Err(invalid("schedule.working.device.id", "empty"));
        }
        unique(
            "schedule.working.device.bars",
            d.bars.iter().map(String::as_str),
        )?;
        if let Some(b) = d
            .bars
            .iter()
            .find(|b| s.reference.iter().any(|r| &r.bar == *b))
        {
            return Err(invalid(
                "schedule.working.device.bars",
                &format!("`{b}` is also a reference bar"),
            ));
        }
        let min_mm = self
            .plate
            .length
            .iter()
            .map(|l| l.mm)
            .fold(f64::INFINITY, f64::min);
        if !(d.distance_mm.is_finite() && d.distance_mm >= min_mm) {
            return Err(invalid(
                "schedule.working.device.distance_mm",
                "must be at least the shortest plate length",
            ));
        }
        if let Some(h) = &d.hexapod {
            if d.bars.len() != 6 {
                return Err(invalid(
                    "schedule.working.device.bars",
                    "a hexapod needs six bars (its legs 1-6, in order)",
                ));
            }
            h.validate("schedule.working.device.hexapod")?;
        }
        tilt("schedule.working.device.tilt_deg", d.tilt_deg)
    }

    fn validate_geometry(&self) -> Result<(), SimError> {
        let g = &self.geometry;
        bounded("geometry.scale_ppm", g.scale_ppm, g.scale_sd_ppm, 1000.0)?;
        bounded(
            "geometry.nonlinearity_ppm_per_mm",
            g.nonlinearity_ppm_per_mm,
            g.nonlinearity_sd_ppm_per_mm,
            1.0,
        )?;
        bounded(
            "geometry.cosine_mrad",
            g.cosine_mrad,
            g.cosine_sd_mrad,
            100.0,
        )?;
        bounded(
            "geometry.zero_offset_um",
            g.zero_offset_um,
            g.zero_offset_sd_um,
            1000.0,
        )?;
        non_negative("geometry.scale_sd_ppm", g.scale_sd_ppm)?;
        non_negative(
            "geometry.nonlinearity_sd_ppm_per_mm",
            g.nonlinearity_sd_ppm_per_mm,
        )?;
        non_negative("geometry.cosine_sd_mrad", g.cosine_sd_mrad)?;
        non_negative("geometry.zero_offset_sd_um", g.zero_offset_sd_um)?;
        let sag = &g.sag;
        finite("geometry.sag.amplitude_um", sag.amplitude_um)?;
        if sag.amplitude_um.abs() > 100.0 {
            return Err(invalid("geometry.sag.amplitude_um", "beyond ±100 µm"));
        }
        non_negative("geometry.sag.spread", sag.spread)?;
        if sag.spread > 1.0 {
            return Err(invalid(
                "geometry.sag.spread",
                "above 1 (log-normal relative spread)",
            ));
        }
        positive("geometry.sag.ref_mm", sag.ref_mm)?;
        if !(sag.exponent.is_finite() && sag.exponent.abs() <= 10.0) {
            return Err(invalid("geometry.sag.exponent", "must be in [-10, 10]"));
        }
        Ok(())
    }

    fn validate_mismatch(&self) -> Result<(), SimError> {
        for (i, m) in self.mismatch.iter().enumerate() {
            let key = |f: &str| format!("mismatch[{i}].{f}");
            if m.bar.is_empty() {
                return Err(invalid(&key("bar"), "empty"));
            }
            for (f, v) in [
                ("alpha_factor", m.alpha_factor),
                ("beta_factor", m.beta_factor),
                ("tau_r_factor", m.tau_r_factor),
                ("tau_s_factor", m.tau_s_factor),
                ("sag_factor", m.sag_factor),
            ] {
                if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
                    return Err(invalid(&key(f), "must be in [0, 100]"));
                }
            }
            if !(m.tau_r_factor > 0.0 && m.tau_s_factor > 0.0) {
                return Err(invalid(
                    &key("tau_r_factor"),
                    "time-constant factors must be positive",
                ));
            }
        }
        unique("mismatch.bar", self.mismatch.iter().map(|m| m.bar.as_str()))
    }

    fn validate_effects(&self) -> Result<(), SimError> {
        let e = &self.effects;
        let h = &e.head_heating;
        finite("effects.head_heating.amplitude_um", h.amplitude_um)?;
        positive("effects.head_heating.tau_s", h.tau_s)?;
        non_negative("effects.head_heating.spread", h.spread)?;
        positive("effects.head_heating.mean_on_h", h.mean_on_h)?;
        positive("effects.head_heating.mean_off_h", h.mean_off_h)?;
        let [off_lo, off_hi] = h.daily_off_h;
        if !(off_lo > 0.0 && off_lo <= off_hi && off_hi < 24.0) {
            return Err(invalid(
                "effects.head_heating.daily_off_h",
                "must be [shortest, longest] hours with 0 < shortest <= longest < 24",
            ));
        }
        finite(
            "effects.second_path.gain_ppm_per_k",
            e.second_path.gain_ppm_per_k,
        )?;
        positive("effects.second_path.tau_s", e.second_path.tau_s)?;
        non_negative("effects.second_path.spread", e.second_path.spread)?;
        let w = e.sensor_gradient.weight_t2;
        if !(0.0..=1.0).contains(&w) {
            return Err(invalid(
                "effects.sensor_gradient.weight_t2",
                "must be in [0, 1]",
            ));
        }
        finite("effects.settling.amplitude_um", e.settling.amplitude_um)?;
        positive("effects.settling.tau_s", e.settling.tau_s)?;
        finite(
            "effects.plate_expansion.cte_ppm_per_k",
            e.plate_expansion.cte_ppm_per_k,
        )?;
        finite("effects.creep.rate_um_per_day", e.creep.rate_um_per_day)?;
        non_negative("effects.creep.spread", e.creep.spread)?;
        self.validate_hidden()?;
        self.validate_heat_source()
    }

    fn validate_heat_source(&self) -> Result<(), SimError> {
        let h = &self.effects.heat_source;
        let taken = [
            "T1",
            "T2",
            "P1",
            self.effects.hidden_channel.sensor_id.as_str(),
        ];
        if h.enabled && (h.sensor_id.is_empty() || taken.contains(&h.sensor_id.as_str())) {
            return Err(SimError::Invalid {
                key: "effects.heat_source.sensor_id".into(),
                reason: format!("{:?} is empty or names another sensor", h.sensor_id),
            });
        }
        finite("effects.heat_source.excess_k", h.excess_k)?;
        let hours_ok = (0.0..=24.0).contains(&h.on_hour)
            && (0.0..=24.0).contains(&h.off_hour)
            && h.on_hour < h.off_hour;
        if !hours_ok {
            return Err(invalid(
                "effects.heat_source.on_hour",
                "on_hour and off_hour must be hours of the day, on before off",
            ));
        }
        positive("effects.heat_source.signal_tau_s", h.signal_tau_s)?;
        non_negative("effects.heat_source.noise_k", h.noise_k)?;
        finite("effects.heat_source.fixed_ppm_per_k", h.fixed_ppm_per_k)?;
        finite("effects.heat_source.scale_ppm_per_k", h.scale_ppm_per_k)?;
        positive("effects.heat_source.tau_s", h.tau_s)?;
        non_negative("effects.heat_source.spread", h.spread)
    }

    fn validate_hidden(&self) -> Result<(), SimError> {
        let h = &self.effects.hidden_channel;
        if h.sensor_id.is_empty() || ["T1", "T2", "P1"].contains(&h.sensor_id.as_str()) {
            return Err(invalid(
                "effects.hidden_channel.sensor_id",
                "empty or taken (T1, T2, P1)",
            ));
        }
        finite("effects.hidden_channel.base_c", h.base_c)?;
        finite("effects.hidden_channel.amplitude_k", h.amplitude_k)?;
        positive("effects.hidden_channel.mean_on_h", h.mean_on_h)?;
        positive("effects.hidden_channel.mean_off_h", h.mean_off_h)?;
        positive("effects.hidden_channel.signal_tau_s", h.signal_tau_s)?;
        non_negative("effects.hidden_channel.noise_k", h.noise_k)?;
        finite("effects.hidden_channel.gain_um_per_k", h.gain_um_per_k)?;
        positive("effects.hidden_channel.tau_s", h.tau_s)?;
        non_negative("effects.hidden_channel.spread", h.spread)
    }
}
