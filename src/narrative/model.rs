//! What the fits could not do, in words: the parameters a bar's data cannot determine
//! (`summary.json`'s `not_identifiable`, `report.md`, the bar's figure).

use crate::model::WhyNotIdentifiable;

/// Why a bar's data cannot determine the parameters, and what to do about it.
pub fn not_identifiable_reason(why: &WhyNotIdentifiable) -> String {
    match why {
        WhyNotIdentifiable::OneLength { i_p_mm } => format!(
            "every fitted mount of the bar is at one length (I_p = {i_p_mm:.3} mm): the scale's \
             expansion (beta, tau_S) cannot be told from the fixed part's with one length; \
             alpha_ppm_per_k and tau_r_s describe the whole bar at this length (alpha + beta I_p / \
             I_min when the time constants are close); mount the bar on two lengths to separate them"
        ),
        WhyNotIdentifiable::AtModelLimit { tau, limit_s } if *limit_s > 1.0 => format!(
            "the fit ran {tau} to the model's limit ({limit_s:.0e} s, about {:.0} years); a lag \
             that slow is the running integral of its input over the campaign; only the ratio of \
             its gains to {tau} is determined, not either; a model bends like this to mimic an \
             effect it lacks (diagnosis.json → candidates)",
            limit_s / (365.25 * 86_400.0)
        ),
        WhyNotIdentifiable::AtModelLimit { tau, limit_s } => format!(
            "the fit ran {tau} to the model's limit ({limit_s} s); the lag follows its input \
             within the readings' spacing; the data determine its gains, not {tau}; a \
             model bends like this to mimic an effect it lacks (diagnosis.json → candidates)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_time_constant_at_the_limit_names_the_limit_and_what_is_left() {
        let slow = not_identifiable_reason(&WhyNotIdentifiable::AtModelLimit {
            tau: "tau_s_s".into(),
            limit_s: 1e9,
        });
        assert!(
            slow.starts_with(
                "the fit ran tau_s_s to the model's limit (1e9 s, about 32 years); a lag that slow \
                 is the running integral"
            ),
            "{slow}"
        );
        assert!(
            slow.contains("only the ratio of its gains to tau_s_s"),
            "{slow}"
        );
        let fast = not_identifiable_reason(&WhyNotIdentifiable::AtModelLimit {
            tau: "tau_r_s".into(),
            limit_s: 1.0,
        });
        assert!(
            fast.starts_with("the fit ran tau_r_s to the model's limit (1 s); the lag follows"),
            "{fast}"
        );
    }

    #[test]
    fn one_length_names_the_travel_and_the_remedy() {
        let text = not_identifiable_reason(&WhyNotIdentifiable::OneLength { i_p_mm: 95.0004 });
        assert!(
            text.starts_with("every fitted mount of the bar is at one length (I_p = 95.000 mm)"),
            "{text}"
        );
        assert!(
            text.ends_with("mount the bar on two lengths to separate them"),
            "{text}"
        );
    }
}
