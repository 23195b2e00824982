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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
