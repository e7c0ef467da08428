//! Your first grid component: `limiter`, y = u clamped to ±limit, counting how often it clamped.
//! This program is the host that steps it; `limited.lua` declares it and puts it on a grid.
use modbot_grid::component::Released;
use modbot_grid::component::{Component, ComponentError, ComponentInfo, ParamDecl, ParamType};
use modbot_grid::component::{ParamValue, Params, PortDecl, PortType, PortValue};

struct Limiter {
    limit: f64,
    clamped: i64,
}

impl Component for Limiter {
    /// At every release: no allocation, no clock, no blocking — the grid's real-time path.
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let u = inputs[0].as_f64();
        let y = u.clamp(-self.limit, self.limit);
        self.clamped += i64::from(y != u);
        outputs[0] = PortValue::F64(y);
        outputs[1] = PortValue::I64(self.clamped);
    }
}

fn info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    Ok(ComponentInfo {
        type_name: "limiter",
        doc: "y = u clamped to ±limit; clamped = how often it clamped",
        inputs: vec![PortDecl::new("u", PortType::F64)],
        outputs: vec![
            PortDecl::new("y", PortType::F64),
            PortDecl::new("clamped", PortType::I64),
        ],
        params: vec![ParamDecl::optional(
            "limit",
            ParamType::F64,
            ParamValue::F64(1.0),
        )],
    })
}

fn make(params: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let limit = params.f64("limit")?;
    Ok(Box::new(Limiter { limit, clamped: 0 }))
}

fn main() -> std::process::ExitCode {
    let mut registry = modbot_components::builtin();
    registry.register(info, make);
    modbot_grid_processes::host_process::host_main("modbot-first-component", registry)
}
