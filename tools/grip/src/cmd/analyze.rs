//! `grip analyze`: the linear analysis of paper §III (grip_tcs::analysis).
//!
//! - `grip analyze`: the vehicle parameters used, each transfer function as
//!   polynomials with its poles, the K_MFC bound (4) for the configured
//!   gains, SRC's gains against their derivation for the vehicle, and the
//!   ν-gap table (ours beside the paper's).
//! - `grip analyze gap --p1 NUM/DEN --p2 NUM/DEN`: the ν-gap of any two SISO
//!   transfer functions, coefficients highest power first, comma- or
//!   space-separated (`--p1 100/2,1 --p2 "100 / 2 -1"`).

use anyhow::{Context, bail};
use grip_physics::{G, RoadCatalogue, VehicleParams};
use grip_tcs::analysis::gaps::{
    GapSetup, PAPER_CLASSES, TABLE_II, paper_classes, structure_gaps, worst,
};
use grip_tcs::analysis::poly::fmt_num;
use grip_tcs::analysis::tf::fmt_roots;
use grip_tcs::analysis::vehicle_tf::{
    SRC_GAIN_RATIO, j_real, kmfc_bound, mfc_omega_diff, mfc_plant, mtte_gain, mtte_observer_plant,
    mtte_tzw_grip, mtte_tzw_paper, src_gain_warning, src_gains, src_gains_off, src_slip,
    src_slip_tf, src_vdiff_tf,
};
use grip_tcs::analysis::{NuGap, Tf, nu_gap};

use super::Ctx;

/// The paper's HPF time constant (Table IV), reported beside the configured one.
const PAPER_TAU_HPF: f64 = 1000.0;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    cmd: Option<Sub>,
    /// Motor torque constant K, N m/A (the paper's undefined "motor gain"),
    /// 1e-6 to 1e6.
    #[arg(long, default_value_t = 1.0)]
    k_motor: f64,
    /// Chassis speed at the operating point, km/h (SRC slip plant), 0.001
    /// to 1000.
    #[arg(long, default_value_t = 20.0)]
    speed_kmh: f64,
    /// Road the SRC's model assumes without ARTE.
    #[arg(long, default_value = "asphalt")]
    src_nominal_road: String,
    /// Vehicle and sensors (default: `<config-dir>/vehicle.toml`); e.g.
    /// config/vehicles/front-mic.toml, or your own car's file, as `grip sim`
    /// and `grip drive` take it.
    #[arg(long)]
    vehicle: Option<std::path::PathBuf>,
}

#[derive(clap::Subcommand)]
enum Sub {
    /// Vinnicombe ν-gap of two SISO transfer functions.
    Gap(GapArgs),
}

#[derive(clap::Args)]
struct GapArgs {
    /// P1 as NUM/DEN, coefficients highest power first, e.g. `100/2,1`.
    #[arg(long, allow_hyphen_values = true)]
    p1: String,
    /// P2 as NUM/DEN, e.g. `100/2,-1` or "100 / 2 -1".
    #[arg(long, allow_hyphen_values = true)]
    p2: String,
}

pub fn run(ctx: &Ctx, args: Args) -> anyhow::Result<()> {
    match args.cmd {
        Some(Sub::Gap(g)) => run_gap(&g),
        None => run_report(ctx, &args),
    }
}

/// Parse `NUM/DEN` into a transfer function; errors name the argument.
pub fn parse_tf(arg: &str, text: &str) -> anyhow::Result<Tf> {
    let parts: Vec<&str> = text.split('/').collect();
    if parts.len() != 2 {
        bail!("{arg} `{text}`: expected NUM/DEN with exactly one `/` (e.g. `100/2,1`)");
    }
    let num = parse_coeffs(arg, "numerator", parts[0])?;
    let den = parse_coeffs(arg, "denominator", parts[1])?;
    if den.iter().all(|&c| c == 0.0) {
        bail!("{arg} `{text}`: the denominator is zero");
    }
    Tf::from_coeffs(&num, &den).with_context(|| format!("{arg} `{text}`"))
}

fn parse_coeffs(arg: &str, which: &str, s: &str) -> anyhow::Result<Vec<f64>> {
    let s = s.trim();
    if s.is_empty() {
        bail!("{arg}: the {which} is empty (expected coefficients highest power first)");
    }
    // commas separate; spaces separate too when there is no comma between
    let fields: Vec<&str> = if s.contains(',') {
        s.split(',').map(str::trim).collect()
    } else {
        s.split_whitespace().collect()
    };
    let mut out = Vec::with_capacity(fields.len());
    for (i, f) in fields.iter().enumerate() {
        if f.is_empty() {
            bail!("{arg}: {which} coefficient {} is empty (in `{s}`)", i + 1);
        }
        let x: f64 = f.parse().map_err(|_| {
            anyhow::anyhow!("{arg}: {which} coefficient {} `{f}` is not a number", i + 1)
        })?;
        if !x.is_finite() {
            bail!(
                "{arg}: {which} coefficient {} `{f}` is not a finite number",
                i + 1
            );
        }
        out.push(x);
    }
    Ok(out)
}

fn run_gap(g: &GapArgs) -> anyhow::Result<()> {
    let p1 = parse_tf("--p1", &g.p1)?;
    let p2 = parse_tf("--p2", &g.p2)?;
    let r = nu_gap(&p1, &p2).context("computing the ν-gap")?;
    println!("P1 = {}", p1.to_pretty());
    println!("     poles: {}", fmt_roots(&p1.poles()?));
    println!("P2 = {}", p2.to_pretty());
    println!("     poles: {}", fmt_roots(&p2.poles()?));
    print_gap(&r);
    Ok(())
}

fn print_gap(r: &NuGap) {
    println!("nu-gap delta_nu(P1, P2) = {:.6}", r.delta);
    println!(
        "sup_w kappa(P1(jw), P2(jw)) = {:.6} at w = {} rad/s",
        r.kappa_sup,
        if r.omega_sup.is_infinite() {
            "inf".to_string()
        } else {
            fmt_num(r.omega_sup)
        }
    );
    println!(
        "winding condition: {} (1 + P2~P1 {} on the imaginary axis; wno = {}, eta(P1) = {}, eta(P2) = {}, eta0(P2) = {}: wno + eta(P1) - eta(P2) - eta0(P2) = {})",
        if r.winding_ok {
            "holds"
        } else {
            "FAILS, so delta_nu = 1"
        },
        if r.vanishes_on_axis {
            "vanishes"
        } else {
            "does not vanish"
        },
        r.wno,
        r.eta1,
        r.eta2,
        r.eta0_2,
        r.wno + r.eta1 as i64 - r.eta2 as i64 - r.eta0_2 as i64
    );
    if r.cancelled > 0 {
        println!(
            "({} common pole/zero factor(s) cancelled first)",
            r.cancelled
        );
    }
}

/// SRC's gains against their derivation for this vehicle
/// ([`src_gains`]), one row per key with its verdict, and the warning of
/// [`src_gain_warning`] under it when one does not suit.
fn src_gains_table(
    v: &VehicleParams,
    vehicle_path: &std::path::Path,
    src: &grip_tcs::SrcParams,
    ctl_path: &std::path::Path,
) -> anyhow::Result<()> {
    let g = src_gains(v)?;
    let off = src_gains_off(v, src)?;
    println!(
        "\n== SRC gains: symmetric optimum for the slip at the friction peak (an integrator (1 - lambda)/(J_w omega) behind tau_m) =="
    );
    println!(
        "  (`ok?`: kp and ti within {}x either way of their derivation, kp_recover inside its interval: above it recovery\n   overshoots into a limit cycle on snow, below it the torque recovers slowly after a cut)",
        fmt_num(SRC_GAIN_RATIO)
    );
    println!(
        "  {:<12} {:>12}  {:<64} {:>4}",
        "[src] key", "configured", "derived for this vehicle", "ok?"
    );
    let rows = [
        (
            "kp",
            format!("{} N m s", fmt_num(src.kp)),
            format!("J_w/(2 tau_m) = {} N m s", fmt_num(g.kp)),
        ),
        (
            "ti",
            format!("{} s", fmt_num(src.ti)),
            format!("4 tau_m = {} s", fmt_num(g.ti)),
        ),
        (
            "kp_recover",
            format!("{} N m s", fmt_num(src.kp_recover)),
            format!(
                "[J_w/(2 tau_m), (J_w + (M/n) r^2)/(2 tau_m)] = [{}, {}] N m s",
                fmt_num(g.kp_recover_min),
                fmt_num(g.kp_recover_max)
            ),
        ),
    ];
    for (key, configured, derived) in rows {
        let ok = if off.iter().any(|o| o.key() == key) {
            "NO"
        } else {
            "yes"
        };
        println!("  {key:<12} {configured:>12}  {derived:<64} {ok:>4}");
    }
    if let Some(w) = src_gain_warning(v, vehicle_path, src, ctl_path)? {
        println!("  warning: {w}");
    }
    Ok(())
}

/// The "slip noise" section: the vehicle's sensors put through the road
/// belief's slip and filter at 10, 20 and 40 km/h
/// ([`grip_tcs::analysis::sensors::slip_noise`]) beside `fusion.sigma_lambda`,
/// and [`grip_tcs::analysis::sensors::sensor_warning`] under it when they
/// are noisier than it assumes.
fn sensor_noise_table(
    v: &VehicleParams,
    sensors: &grip_physics::SensorParams,
    vehicle_path: &std::path::Path,
    ctl: &grip_tcs::ControllersConfig,
    ctl_path: &std::path::Path,
) {
    use grip_tcs::analysis::sensors::{NOISE_TOLERANCE, sensor_warning, slip_noise};
    let dt = 1.0 / ctl.loop_.rate_hz;
    let f = &ctl.fusion;
    println!(
        "\n== Slip noise of the vehicle's sensors (a wheel rolling without slip through [sensors], the road belief's slip and its {} s filter) ==",
        fmt_num(f.tau_slip_s)
    );
    if !sensors.v_available {
        println!(
            "  no V (sensors.v_available = false): the road belief measures no slip, and SRC, which needs V, passes the demand through"
        );
        return;
    }
    println!(
        "  encoder_ppr {} over omega_window {} at {} Hz, omega_noise_std {} rad/s, v_noise_std {} m/s, v_lsb {} m/s",
        sensors.encoder_ppr,
        sensors.omega_window,
        fmt_num(ctl.loop_.rate_hz),
        fmt_num(sensors.omega_noise_std),
        fmt_num(sensors.v_noise_std),
        fmt_num(sensors.v_lsb)
    );
    println!("  {:>10} {:>10} {:>10}", "speed", "raw sigma", "filtered");
    for kmh in [10.0, 20.0, 40.0] {
        if let Some(n) = slip_noise(v, sensors, f.tau_slip_s, dt, kmh / 3.6) {
            println!(
                "  {:>6} km/h {:>10.4} {:>10.4}",
                fmt_num(kmh),
                n.raw,
                n.filtered
            );
        }
    }
    let warning = sensor_warning(v, sensors, vehicle_path, f, ctl_path, dt);
    println!(
        "  fusion.sigma_lambda = {} (within {NOISE_TOLERANCE}x at 10 km/h: {})",
        fmt_num(f.sigma_lambda),
        if warning.is_some() { "NO" } else { "yes" }
    );
    if let Some(w) = warning {
        println!("  warning: {w}");
    }
}

fn tf_line(name: &str, tf: &Tf) -> anyhow::Result<()> {
    println!("  {name}");
    println!(
        "    num: [{}]  = {}",
        coeffs(&tf.num.coeffs_desc()),
        tf.num.to_pretty()
    );
    println!(
        "    den: [{}]  = {}",
        coeffs(&tf.den.coeffs_desc()),
        tf.den.to_pretty()
    );
    println!("    poles: {}", fmt_roots(&tf.poles()?));
    Ok(())
}

fn coeffs(c: &[f64]) -> String {
    c.iter().map(|&x| fmt_num(x)).collect::<Vec<_>>().join(", ")
}

/// The range of `--k-motor`, N m/A: a motor's torque constant is of the
/// order of 1; far outside it the model's coefficients overflow (1e308
/// made a transfer function's numerator infinite) or vanish (5e-324 made
/// every K_MFC bound infinite).
const K_MOTOR_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=1e6;

/// The range of `--speed-kmh`, km/h: an operating point of a road vehicle;
/// far below it the SRC slip plant degenerates (1e-200 km/h: a zero
/// polynomial), far above it its coefficients overflow.
const SPEED_KMH_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// A flag's value as the user would have typed it: `1e308`, not the 309
/// digits `{}` writes for it.
fn shown(x: f64) -> String {
    let a = x.abs();
    if x != 0.0 && a.is_finite() && !(1e-4..1e6).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// `--k-motor` and `--speed-kmh` within [`K_MOTOR_RANGE`] and
/// [`SPEED_KMH_RANGE`], before anything is read or printed; the error
/// names the flag, its value and the range.
fn check_operating_point(args: &Args) -> anyhow::Result<()> {
    for (flag, value, range, unit, why) in [
        (
            "--k-motor",
            args.k_motor,
            K_MOTOR_RANGE,
            "N m/A",
            "a motor's torque constant is of the order of 1 N m/A; far outside the range the model's coefficients overflow or vanish",
        ),
        (
            "--speed-kmh",
            args.speed_kmh,
            SPEED_KMH_RANGE,
            "km/h",
            "the chassis speed of the SRC slip plant's operating point; far outside the range its coefficients overflow or vanish",
        ),
    ] {
        if !(value.is_finite() && range.contains(&value)) {
            bail!(
                "{flag} {}: must be a finite number from {} to {} {unit} ({why})",
                shown(value),
                shown(*range.start()),
                shown(*range.end())
            );
        }
    }
    Ok(())
}

fn run_report(ctx: &Ctx, args: &Args) -> anyhow::Result<()> {
    check_operating_point(args)?;
    let dir = grip_config::ConfigDir::new(&ctx.config_dir);
    let vehicle_path = args.vehicle.clone().unwrap_or_else(|| dir.vehicle_path());
    let (v, sensors) = grip_config::load_vehicle(&vehicle_path)?;
    let cat: RoadCatalogue = dir.roads()?;
    // checked before anything is printed
    let nominal = cat.get(&args.src_nominal_road).with_context(|| {
        format!(
            "--src-nominal-road `{}` is not a road of the catalogue {} ({})",
            args.src_nominal_road,
            dir.roads_path().display(),
            cat.names()
        )
    })?;
    let ctl_path = dir.file("controllers.toml");
    let ctl = grip_config::load_controllers(&ctl_path)?;
    let k = args.k_motor;
    let m = v.mass_share();
    let jm = v.j_model();

    println!("== Vehicle ({}) ==", vehicle_path.display());
    println!(
        "  M = {} kg, n = {} driven wheels -> the wheel carries M/n = {} kg, {}",
        fmt_num(v.mass),
        fmt_num(v.n_driven),
        fmt_num(m),
        normal_force_text(&v)
    );
    println!(
        "  J_w = {} kg m^2, r = {} m, M_w = J_w / r^2 = {} kg, J_model = J_w + (M/n) r^2 = {} kg m^2",
        fmt_num(v.j_w),
        fmt_num(v.r),
        fmt_num(v.j_w / (v.r * v.r)),
        fmt_num(jm)
    );
    println!(
        "  tau_1 = tau_m = {} s, K = {} N m/A (assumed), operating speed {} km/h",
        fmt_num(v.tau_m),
        fmt_num(k),
        fmt_num(args.speed_kmh)
    );
    println!(
        "  controllers ({}): K_MFC = {} N m s/rad, tau_2 = tau_hpf = {} s; MTTE alpha = {}, tau_obs = {} s, tau_lpf = {} s",
        ctl_path.display(),
        fmt_num(ctl.mfc.k_mfc),
        fmt_num(ctl.mfc.tau_hpf),
        fmt_num(ctl.mtte.alpha),
        fmt_num(ctl.mtte.tau_obs),
        fmt_num(ctl.mtte.tau_lpf)
    );

    println!("\n== Roads ({}) ==", dir.roads_path().display());
    println!(
        "  {:<14} {:>9} {:>8} {:>12} {:>8}",
        "road", "lambda_opt", "mu_peak", "J(lambda_opt)", "Delta"
    );
    for r in cat.iter() {
        let jr = j_real(&v, r.lambda_opt());
        println!(
            "  {:<14} {:>9.4} {:>8.4} {:>12.4} {:>8.4}",
            r.name(),
            r.lambda_opt(),
            r.mu_peak(),
            jr,
            jm / jr - 1.0
        );
    }

    let lam0 = nominal.lambda_opt();
    println!(
        "\n== Transfer functions (operating point: {} at lambda_o = lambda_opt = {:.4}) ==",
        nominal.name(),
        lam0
    );
    tf_line(
        "MFC plant w/I = K / (J s (tau_m s + 1)), model J = J_model",
        &mfc_plant(&v, k, 0.0)?,
    )?;
    tf_line(
        &format!("MFC plant, real J = J(lambda_o) = {:.4}", j_real(&v, lam0)),
        &mfc_plant(&v, k, lam0)?,
    )?;
    tf_line(
        &format!(
            "(3) w_diff/I_ref, corrected (HPF zero), J_m = J_model, J_r = J(lambda_o), K_MFC = {}, tau_2 = {} s",
            fmt_num(ctl.mfc.k_mfc),
            fmt_num(ctl.mfc.tau_hpf)
        ),
        &mfc_omega_diff(&v, k, jm, j_real(&v, lam0), ctl.mfc.k_mfc, ctl.mfc.tau_hpf)?,
    )?;
    println!(
        "  (6)-(8) SRC lambda/T (T in N m) at lambda* = {:.4}, V = {} km/h, on each road:",
        lam0,
        fmt_num(args.speed_kmh)
    );
    let v_w = args.speed_kmh / 3.6 / (1.0 - lam0);
    for r in cat.iter() {
        let a = r.dmu_dlambda(lam0);
        let a = if a.abs() < grip_tcs::analysis::gaps::SLOPE_ZERO {
            0.0
        } else {
            a
        };
        let s = src_slip(&v, lam0, a, v_w)?;
        let tf = src_slip_tf(&s, &v, false)?;
        println!(
            "    {:<14} a = {:>9.4}  N_e = {:>8.1} N  tau = {:>10} s  num [{}] den [{}]  pole {}",
            r.name(),
            a,
            s.n_e,
            fmt_num(s.tau),
            coeffs(&tf.num.coeffs_desc()),
            coeffs(&tf.den.coeffs_desc()),
            fmt_roots(&tf.poles()?)
        );
    }
    tf_line(
        &format!("(9) V_diff/I, corrected, at lambda = {lam0:.4}"),
        &src_vdiff_tf(&v, k, lam0)?,
    )?;
    let kg = mtte_gain(&v, ctl.mtte.alpha)?;
    println!(
        "  MTTE gain K = J_w/(alpha (M/n) r) + r = {} m (alpha = {})",
        fmt_num(kg),
        fmt_num(ctl.mtte.alpha)
    );
    tf_line(
        "(11) T_zw as in the paper (observer on T*, tau = tau_lpf), J_n = J(lambda_o)",
        &mtte_tzw_paper(&v, ctl.mtte.alpha, ctl.mtte.tau_lpf, lam0)?,
    )?;
    tf_line(
        "T_zw of grip's MTTE (observer on measured T with tau_obs, LPF tau_lpf), J_n = J(lambda_o)",
        &mtte_tzw_grip(&v, ctl.mtte.alpha, ctl.mtte.tau_obs, ctl.mtte.tau_lpf, lam0)?,
    )?;
    tf_line(
        "MTTE loop element r F_d/T* at J(lambda_o)",
        &mtte_observer_plant(&v, lam0, ctl.mtte.tau_obs)?,
    )?;

    println!(
        "\n== K_MFC bound (4): K_MFC <= J_m (tau_2 - tau_1)^2 / (4 tau_2^2 tau_1 K Delta), J_m = J_model =="
    );
    println!(
        "  (a real-pole (no overshoot) condition: the loop is Hurwitz for every K_MFC >= 0 when Delta > 0)"
    );
    println!(
        "  (the last bound adds the MFC's noise low-pass to the loop's lag: tau_1 = tau_m + tau_noise = {} s;\n   `K_MFC ok?` is judged against it)",
        fmt_num(v.tau_m + ctl.mfc.tau_noise)
    );
    println!(
        "  {:<26} {:>8} {:>16} {:>16} {:>22} {:>10}",
        "real inertia J_r",
        "Delta",
        format!("tau_2={}s", fmt_num(PAPER_TAU_HPF)),
        format!("tau_2={}s", fmt_num(ctl.mfc.tau_hpf)),
        format!("tau_2={}s,+tau_noise", fmt_num(ctl.mfc.tau_hpf)),
        "K_MFC ok?"
    );
    let mut rows: Vec<(String, f64)> = cat
        .iter()
        .map(|r| {
            (
                format!("{} (lambda_opt)", r.name()),
                j_real(&v, r.lambda_opt()),
            )
        })
        .collect();
    rows.push(("free-spinning wheel (J_w)".into(), v.j_w));
    for (name, jr) in rows {
        let b_paper = kmfc_bound(jm, jr, v.tau_m, PAPER_TAU_HPF, k)?;
        let b_conf = kmfc_bound(jm, jr, v.tau_m, ctl.mfc.tau_hpf, k)?;
        let b_filt = kmfc_bound(jm, jr, v.tau_m + ctl.mfc.tau_noise, ctl.mfc.tau_hpf, k)?;
        println!(
            "  {:<26} {:>8.4} {:>16.4} {:>16.4} {:>22.4} {:>10}",
            name,
            b_conf.delta,
            b_paper.bound,
            b_conf.bound,
            b_filt.bound,
            if ctl.mfc.k_mfc <= b_filt.bound {
                "yes"
            } else {
                "NO"
            }
        );
    }
    println!(
        "  configured K_MFC = {} N m s/rad (K = {} N m/A)",
        fmt_num(ctl.mfc.k_mfc),
        fmt_num(k)
    );
    if let Some(w) =
        grip_tcs::analysis::vehicle_tf::kmfc_warning(&v, &vehicle_path, &cat, &ctl.mfc, &ctl_path)?
    {
        println!("  warning: {w}");
    }

    src_gains_table(&v, &vehicle_path, &ctl.src, &ctl_path)?;
    sensor_noise_table(&v, &sensors, &vehicle_path, &ctl, &ctl_path);

    let classes = paper_classes(&cat)?;
    println!(
        "\n== nu-gaps: nominal (what the controller assumes) vs uncertain (the road it meets) =="
    );
    println!("  classes (ARTE reports the first road's table for every member):");
    for c in &classes {
        let names: Vec<&str> = c.members.iter().map(|&i| cat[i].name()).collect();
        println!("    {:<8} {}", c.name, names.join(", "));
    }
    let left_out: Vec<&str> = cat
        .iter()
        .enumerate()
        .filter(|(i, _)| !classes.iter().any(|c| c.members.contains(i)))
        .map(|(_, r)| r.name())
        .collect();
    if !left_out.is_empty() {
        println!("    (in no class, left out: {})", left_out.join(", "));
    }
    println!(
        "  confusion (Table II, rows predicted, columns actual {:?}): {:?}",
        PAPER_CLASSES, TABLE_II
    );
    let setup = GapSetup {
        vehicle: v,
        k_motor: k,
        speed: args.speed_kmh / 3.6,
        mtte_alpha: ctl.mtte.alpha,
        mtte_tau_obs: ctl.mtte.tau_obs,
        src_nominal_road: args.src_nominal_road.clone(),
    };
    let all = structure_gaps(&setup, &cat, &classes, &TABLE_II)?;
    println!(
        "\n  {:<5} | {:>22} {:>10} | {:>32} {:>10} {:>26} | {:>7} {:>7}",
        "TCS",
        "no ARTE: worst",
        "class mean",
        "ARTE: correct class worst",
        "Table II",
        "Table II worst pair",
        "paper",
        "paper"
    );
    println!(
        "  {:<5} | {:>22} {:>10} | {:>32} {:>10} {:>26} | {:>7} {:>7}",
        "", "(road)", "", "(road as table)", "mean", "(road as table)", "no ARTE", "ARTE"
    );
    for s in &all {
        let no = worst(&s.no_arte).context("no cases")?;
        let ok = worst(&s.arte_correct).context("no cases")?;
        let cw = &s.arte_confused_worst;
        println!(
            "  {:<5} | {:>22} {:>10.4} | {:>32} {:>10.4} {:>26} | {:>7} {:>7}",
            s.structure.name(),
            format!("{:.4} ({})", no.gap.delta, no.road),
            s.no_arte_class_mean,
            format!("{:.4} ({} as {})", ok.gap.delta, ok.road, ok.believed),
            s.arte_table2_mean,
            format!("{:.4} ({} as {})", cw.gap.delta, cw.road, cw.believed),
            fmt_num(s.paper.0),
            fmt_num(s.paper.1)
        );
    }
    println!("\n  per road (no ARTE | ARTE, correct class):");
    for s in &all {
        let row: Vec<String> = s
            .no_arte
            .iter()
            .zip(&s.arte_correct)
            .map(|(a, b)| format!("{} {:.4}|{:.4}", a.road, a.gap.delta, b.gap.delta))
            .collect();
        println!("    {:<5} {}", s.structure.name(), row.join("  "));
    }
    println!(
        "\n  Definitions, corrections and why ours differ from the paper: crates/tcs/README.md, \"Analysis\". {} (g = {G}).",
        normal_force_text(&v)
    );
    Ok(())
}

/// The driven wheel's normal force as every line of the report states it:
/// the vehicle's own [`VehicleParams::normal_force`] (what the plant, the
/// controllers and the analysis use), with its formula.
fn normal_force_text(v: &VehicleParams) -> String {
    format!(
        "N = share M g / n = {} x {} kg x {G} m/s^2 / {} = {} N",
        fmt_num(v.driven_load_share),
        fmt_num(v.mass),
        fmt_num(v.n_driven),
        fmt_num(v.normal_force())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One N, with its label, for the shipped profiles: the paper's quarter
    /// car (share 1, n = 4) and the rear-driven front-mic car (share 0.5,
    /// n = 2), whose N the report once gave as M g / n = 6867 N in one line
    /// and 3433.5 N in another.
    #[test]
    fn the_normal_force_is_the_vehicles_own() {
        let config = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        for (file, want) in [
            (
                "vehicle.toml",
                "N = share M g / n = 1 x 1400 kg x 9.81 m/s^2 / 4 = 3433.5 N",
            ),
            (
                "vehicles/front-mic.toml",
                "N = share M g / n = 0.5 x 1400 kg x 9.81 m/s^2 / 2 = 3433.5 N",
            ),
        ] {
            let (v, _) = grip_config::load_vehicle(config.join(file)).unwrap();
            assert_eq!(normal_force_text(&v), want, "{file}");
        }
    }

    #[test]
    fn parses_commas_and_spaces() {
        let a = parse_tf("--p1", "100/2,1").unwrap();
        let b = parse_tf("--p1", " 100 / 2 1 ").unwrap();
        assert_eq!(a, b);
        assert_eq!(a.den.coeffs_desc(), vec![2.0, 1.0]);
        let c = parse_tf("--p2", "1, -2/1,-1").unwrap();
        assert_eq!(c.num.coeffs_desc(), vec![1.0, -2.0]);
    }

    #[test]
    fn report_runs_on_the_shipped_config() {
        let ctx = Ctx {
            config_dir_given: false,
            config_dir: std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"),
        };
        let args = Args {
            cmd: None,
            k_motor: 1.0,
            speed_kmh: 20.0,
            src_nominal_road: "asphalt".into(),
            vehicle: None,
        };
        run(&ctx, args).unwrap();
        let bad = Args {
            cmd: None,
            k_motor: 1.0,
            speed_kmh: 20.0,
            src_nominal_road: "moon".into(),
            vehicle: None,
        };
        let e = run(&ctx, bad).unwrap_err().to_string();
        assert!(e.contains("--src-nominal-road `moon`"), "{e}");
    }

    #[test]
    fn rejects_bad_input_naming_the_argument() {
        for (text, want) in [
            ("1,,2/3", "coefficient 2 is empty"),
            ("1/0", "denominator is zero"),
            ("1/0,0", "denominator is zero"),
            ("abc/1", "`abc` is not a number"),
            ("1/NaN", "not a finite number"),
            ("1/inf", "not a finite number"),
            ("1,2", "exactly one `/`"),
            ("1/2/3", "exactly one `/`"),
            ("/1", "numerator is empty"),
        ] {
            let e = parse_tf("--p2", text).unwrap_err().to_string();
            assert!(e.starts_with("--p2"), "{text}: {e}");
            assert!(e.contains(want), "{text}: {e}");
        }
    }
}
