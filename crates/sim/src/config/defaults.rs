//! The default of every configuration section: what an empty `pipelines/sim-*.toml` simulates
//! (a 6-bar, 4-day campaign with every extra effect off).
//!
//! Separate from the section types so that the types read as the file format and the defaults
//! as one list of the numbers a campaign starts from.

use super::{
    CalibrationPhase, Creep, EffectsConfig, FleetConfig, GenerationConfig, GeometryConfig,
    HeadHeating, HeadSchedule, HeadStart, HeatSource, HiddenChannel, PlateConfig, PlateExpansion,
    RoomConfig, SagConfig, SagForm, ScheduleConfig, SecondPath, SensorGradient, Settling,
    SimConfig,
};
use chrono::DateTime;
use chrono::Utc;
use dbbcal_core::campaign::PlateLength;

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            campaign_id: "sim".into(),
            start: DateTime::parse_from_rfc3339("2026-11-01T00:00:00Z")
                .expect("constant")
                .with_timezone(&Utc),
            duration_days: 4.0,
            sample_s: 10.0,
            max_internal_step_s: 1.0,
            noise_um: 0.02,
            resolution_nm: 5.0,
            reference_temperature_c: 20.0,
            record_true_error: false,
            plate: PlateConfig::default(),
            bars: Vec::new(),
            fleet: None,
            room: RoomConfig::default(),
            schedule: ScheduleConfig::default(),
            effects: EffectsConfig::default(),
            geometry: GeometryConfig::default(),
            mismatch: Vec::new(),
            generation: GenerationConfig::default(),
        }
    }
}

impl Default for PlateConfig {
    fn default() -> Self {
        let length = |id: &str, mm: f64, u_um: f64| PlateLength {
            id: id.into(),
            mm,
            u_um,
        };
        Self {
            material: "zerodur".into(),
            cte_ppm_per_k: 0.0,
            tilt_deg: 60.0,
            thermal_tau_s: 3.0 * 3600.0,
            length: vec![
                length("min", 250.0006, 0.15),
                length("mid", 325.0011, 0.15),
                length("max", 400.0019, 0.20),
            ],
        }
    }
}

impl Default for FleetConfig {
    fn default() -> Self {
        Self {
            n_bars: 6,
            id_prefix: "B".into(),
            fixed_length_mm: 230.0,
            fixed_length_sd_mm: 0.3,
            alpha_ppm_per_k: 2.0,
            alpha_sd_ppm_per_k: 0.15,
            beta_ppm_per_k: 0.6,
            beta_sd_ppm_per_k: 0.05,
            tau_r_s: 3000.0,
            tau_s_s: 1500.0,
            tau_rel_sd: 0.1,
        }
    }
}

impl Default for RoomConfig {
    fn default() -> Self {
        Self {
            mean_c: 20.3,
            daily_amplitude_k: 0.5,
            daily_peak_hour: 15.0,
            ac_period_s: 1200.0,
            ac_amplitude_k: 0.1,
            drift_k_per_day: 0.05,
            wander_k: 0.3,
            door_rate_per_day: 0.0,
            door_amplitude_k: 0.3,
            door_rise_s: 60.0,
            door_decay_s: 600.0,
            setpoint_step_k: 0.0,
            setpoint_half_period_s: 6.0 * 3600.0,
            setpoint_settle_s: 300.0,
            gradient_k: 0.3,
            gradient_daily_k: 0.25,
            gradient_ac_k: 0.05,
            gradient_wander_k: 0.2,
            sensor_noise_k: 0.008,
            temperature_sample_s: 30.0,
            plate_sensor: false,
        }
    }
}

impl Default for ScheduleConfig {
    fn default() -> Self {
        Self {
            mount_days: 1.0,
            gap_minutes: 20.0,
            stagger_minutes: 30.0,
            handling_offset_mm: 2.0,
            lengths: Vec::new(),
            reference: Vec::new(),
            calibration: None,
            working: None,
        }
    }
}

impl Default for CalibrationPhase {
    fn default() -> Self {
        Self {
            tilts_deg: vec![30.0, 60.0, 90.0],
            mount_hours: 3.0,
        }
    }
}

impl Default for SagConfig {
    fn default() -> Self {
        Self {
            amplitude_um: 0.0,
            spread: 0.0,
            form: SagForm::Cos,
            ref_mm: 400.0,
            exponent: 2.0,
        }
    }
}

impl Default for HeadHeating {
    fn default() -> Self {
        Self {
            enabled: false,
            amplitude_um: 1.5,
            tau_s: 900.0,
            spread: 0.2,
            start: HeadStart::SwitchedOn,
            schedule: HeadSchedule::Random,
            mean_on_h: 18.0,
            mean_off_h: 2.0,
            daily_off_h: [1.5, 4.0],
            logs_while_off: false,
        }
    }
}

impl Default for SecondPath {
    fn default() -> Self {
        Self {
            enabled: false,
            gain_ppm_per_k: 0.8,
            tau_s: 300.0,
            spread: 0.2,
        }
    }
}

impl Default for SensorGradient {
    fn default() -> Self {
        Self {
            enabled: false,
            weight_t2: 0.5,
        }
    }
}

impl Default for Settling {
    fn default() -> Self {
        Self {
            enabled: false,
            amplitude_um: 1.0,
            tau_s: 1800.0,
        }
    }
}

impl Default for PlateExpansion {
    fn default() -> Self {
        Self {
            enabled: false,
            cte_ppm_per_k: 1.0,
        }
    }
}

impl Default for Creep {
    fn default() -> Self {
        Self {
            enabled: false,
            rate_um_per_day: 0.1,
            spread: 0.3,
        }
    }
}

impl Default for HiddenChannel {
    fn default() -> Self {
        Self {
            enabled: false,
            sensor_id: "H1".into(),
            base_c: 25.0,
            amplitude_k: 8.0,
            mean_on_h: 3.0,
            mean_off_h: 6.0,
            signal_tau_s: 1200.0,
            noise_k: 0.05,
            gain_um_per_k: 0.05,
            tau_s: 1800.0,
            spread: 0.2,
        }
    }
}

impl Default for HeatSource {
    fn default() -> Self {
        Self {
            enabled: false,
            sensor_id: "C1".into(),
            excess_k: 4.0,
            on_hour: 8.0,
            off_hour: 18.0,
            signal_tau_s: 2400.0,
            noise_k: 0.01,
            fixed_ppm_per_k: 0.25,
            scale_ppm_per_k: 0.15,
            tau_s: 3600.0,
            spread: 0.2,
        }
    }
}
