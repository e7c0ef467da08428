//! The `bus` component's `backend` param and what the EtherCAT backend needs with it.

use modbot_grid::component::{ParamValue, Params, Registry};

fn registry() -> Registry {
    let mut registry = Registry::new();
    crate::robot::register(&mut registry);
    registry
}

fn refusal(params: Params) -> String {
    match registry().info("bus", &params) {
        Ok(_) => panic!("accepted {params:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn an_unknown_backend_is_refused_naming_the_known_ones() {
    let e = refusal(Params::new().with("backend", ParamValue::Text("canopen".into())));
    assert!(
        e.contains("unknown bus backend 'canopen' (known: sim, ethercat)"),
        "{e}"
    );
}

#[test]
fn the_ethercat_backend_without_an_interface_is_refused_before_anything_starts() {
    let e = refusal(Params::new().with("backend", ParamValue::Text("ethercat".into())));
    assert!(e.contains("'interface' is required"), "{e}");
    let with = Params::new()
        .with("backend", ParamValue::Text("ethercat".into()))
        .with("interface", ParamValue::Text("eth1".into()));
    assert!(registry().info("bus", &with).is_ok());
}

#[test]
fn a_bus_on_ethercat_is_made_only_by_the_bus_bridge_process() {
    let params = Params::new()
        .with("backend", ParamValue::Text("ethercat".into()))
        .with("interface", ParamValue::Text("eth1".into()));
    let mut params = params;
    params.set_timing(0.001, 1);
    let e = registry()
        .instantiate("bus", &params)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("bus bridge process"), "{e}");
}
