//! ν-gaps of the three structures with and without ARTE, on the shipped
//! road catalogue's curves (copied from config/roads.toml; grip-config
//! depends on grip-tcs, so it cannot be used here).

use grip_physics::{FrictionModel, Road, RoadCatalogue, VehicleParams};
use grip_tcs::analysis::gaps::{
    GapSetup, Structure, TABLE_II, paper_classes, structure_gaps, worst,
};
use grip_tcs::analysis::vehicle_tf::j_real;

fn catalogue() -> RoadCatalogue {
    let b = |n: &str, c1, c2, c3| Road::burckhardt(n, c1, c2, c3).unwrap();
    RoadCatalogue::new(vec![
        b("asphalt", 1.2801, 23.99, 0.52),
        b("gravel", 0.6212, 20.80, 0.0712),
        b("snow", 0.1946, 94.129, 0.0646),
        b("stone", 1.3713, 6.4565, 0.6691),
        b("wet_asphalt", 0.857, 33.822, 0.347),
        b("wet_stone", 0.4004, 33.708, 0.1204),
        b("ice", 0.05, 306.39, 0.0),
        Road::new(
            "asphalt_mf",
            FrictionModel::Pacejka {
                b: 10.0,
                c: 1.9,
                d: 1.0,
                e: 0.97,
            },
        )
        .unwrap(),
    ])
    .unwrap()
}

#[test]
fn classes_group_the_catalogue() {
    let cat = catalogue();
    let cl = paper_classes(&cat).unwrap();
    let names = |i: usize| -> Vec<&str> { cl[i].members.iter().map(|&m| cat[m].name()).collect() };
    assert_eq!(cl[0].name, "asphalt");
    assert_eq!(names(0), ["asphalt", "wet_asphalt", "asphalt_mf"]);
    assert_eq!(names(1), ["snow"]);
    assert_eq!(names(2), ["stone", "wet_stone"]);
    assert_eq!(names(3), ["gravel"]);
    let small = RoadCatalogue::new(vec![
        Road::burckhardt("asphalt", 1.28, 23.99, 0.52).unwrap(),
    ])
    .unwrap();
    let e = paper_classes(&small).unwrap_err().to_string();
    assert!(e.contains("snow") && e.contains("asphalt"), "{e}");
}

#[test]
fn structure_gaps_are_consistent() {
    let cat = catalogue();
    let cl = paper_classes(&cat).unwrap();
    let setup = GapSetup::default();
    let all = structure_gaps(&setup, &cat, &cl, &TABLE_II).unwrap();
    assert_eq!(all.len(), 3);
    for s in &all {
        let no = worst(&s.no_arte).unwrap();
        let ok = worst(&s.arte_correct).unwrap();
        eprintln!(
            "{:4} no ARTE worst {:.4} ({}), class mean {:.4} | ARTE correct {:.4} ({} as {}), Table II mean {:.4}, confused worst {:.4} ({} as {})",
            s.structure.name(),
            no.gap.delta,
            no.road,
            s.no_arte_class_mean,
            ok.gap.delta,
            ok.road,
            ok.believed,
            s.arte_table2_mean,
            s.arte_confused_worst.gap.delta,
            s.arte_confused_worst.road,
            s.arte_confused_worst.believed
        );
        for c in s.no_arte.iter().chain(&s.arte_correct) {
            assert!((0.0..=1.0).contains(&c.gap.delta));
        }
        // single-member classes read their own table: no gap with ARTE
        for c in s
            .arte_correct
            .iter()
            .filter(|c| c.road == "snow" || c.road == "gravel")
        {
            assert!(c.gap.delta < 1e-9, "{c:?}");
        }
        assert!(s.arte_table2_mean <= s.arte_confused_worst.gap.delta + 1e-12);
        assert!(ok.gap.delta <= s.arte_confused_worst.gap.delta + 1e-12);
    }
}

/// MFC: nominal and true plant differ by the gain J_nom / J_true, and the
/// plant has an integrator, so δ_ν = |ρ − 1| / (ρ + 1) with ρ = J_nom/J_true.
#[test]
fn mfc_gaps_match_closed_form() {
    let cat = catalogue();
    let cl = paper_classes(&cat).unwrap();
    let v = VehicleParams::default();
    let all = structure_gaps(&GapSetup::default(), &cat, &cl, &TABLE_II).unwrap();
    let mfc = all.iter().find(|s| s.structure == Structure::Mfc).unwrap();
    for c in &mfc.no_arte {
        let rho = j_real(&v, 0.0) / j_real(&v, cat.get(&c.road).unwrap().lambda_opt());
        let want = (rho - 1.0).abs() / (rho + 1.0);
        assert!((c.gap.delta - want).abs() < 1e-9, "{c:?} want {want}");
    }
    // the worst without ARTE is dry stone (largest lambda_opt, 0.40)
    assert_eq!(worst(&mfc.no_arte).unwrap().road, "stone");
}

/// SRC without ARTE on snow at asphalt's reference λ* = 0.17, past snow's
/// peak (0.06): the true slip plant is unstable (slope −0.065), but the
/// nominal model linearised at asphalt's own peak is an integrator (a = 0),
/// and an integrator is close in the ν-gap to a slow pole on either side:
/// the winding condition holds and the gap is small. The large SRC gap
/// comes from roads whose slope at λ* is large (stone: fast stable pole).
#[test]
fn src_past_the_peak_is_close_to_the_integrator() {
    let cat = catalogue();
    let cl = paper_classes(&cat).unwrap();
    let all = structure_gaps(&GapSetup::default(), &cat, &cl, &TABLE_II).unwrap();
    let src = all.iter().find(|s| s.structure == Structure::Src).unwrap();
    let snow = src.no_arte.iter().find(|c| c.road == "snow").unwrap();
    assert_eq!((snow.gap.eta1, snow.gap.eta2), (0, 1), "{snow:?}");
    assert!(snow.gap.winding_ok && snow.gap.delta < 0.2, "{snow:?}");
    let stone = src.no_arte.iter().find(|c| c.road == "stone").unwrap();
    assert!(
        stone.gap.delta > 0.8 && stone.gap.omega_sup < 1e-9,
        "{stone:?}"
    );
}
