//! A checked grid as bytes: the image the supervisor writes once per assembly generation and
//! every grid process reads (`modbot_ipc_schema::grid_spec`), so that only the supervisor
//! evaluates the description and a process restarted after the description was edited still
//! serves the grid the system started with.
//!
//! The image holds everything a grid process uses; not the loader's context
//! ([`Assembly::source`]), which stays with the process that reads descriptions.

use std::time::Duration;

use modbot_ipc_schema::grid_spec::{
    self, AssemblyImage, ComponentImage, ConnectionImage, DeclaredImage, GridImage, GridSpecError,
    InfoImage, ParamDeclImage, PortAt, PortImage,
};

use super::{Assembly, ComponentSpec, Connection, GridSpec, GridTiming, PortRef};
use crate::component::{intern, ComponentInfo, DeclaredType, ParamDecl, Params, PortDecl};

impl GridSpec {
    /// This grid as an image (without the loader's context).
    pub fn to_image(&self) -> Vec<u8> {
        let mut out = Vec::new();
        grid_spec::encode(&image_of(self), &mut out);
        out
    }

    /// The grid an image holds: checked as the decoder checks (indices, port types, every input
    /// fed once), so the spec's methods can index it.
    pub fn from_image(bytes: &[u8]) -> Result<GridSpec, GridSpecError> {
        Ok(spec_of(grid_spec::decode(bytes)?))
    }
}

fn image_of(spec: &GridSpec) -> GridImage {
    GridImage {
        base_period_ns: u64::try_from(spec.base_period.as_nanos()).unwrap_or(u64::MAX),
        cpus: spec.cpus.clone(),
        priority: spec.priority,
        mlock: spec.mlock,
        line: spec.line,
        clock: spec.timing.clock,
        track_ticks: spec.timing.track_ticks,
        spin_us: spec.timing.spin_us,
        assembly: spec.assembly.as_ref().map(|a| AssemblyImage {
            name: a.name.clone(),
            generation: a.generation,
            base: a.base,
        }),
        declared: spec
            .declared
            .iter()
            .map(|d| DeclaredImage {
                program: d.program.clone(),
                line: d.line,
                info: info_image(&d.info),
            })
            .collect(),
        components: spec
            .components
            .iter()
            .map(|c| ComponentImage {
                name: c.name.clone(),
                type_name: c.type_name.clone(),
                program: c.program.clone(),
                host: c.host.clone(),
                period: c.period,
                policy: c.policy,
                line: c.line,
                params: c
                    .params
                    .iter()
                    .map(|(n, v)| (n.to_owned(), v.clone()))
                    .collect(),
                info: info_image(&c.info),
            })
            .collect(),
        connections: spec
            .connections
            .iter()
            .map(|c| ConnectionImage {
                from: PortAt {
                    component: c.from.component,
                    port: c.from.port,
                },
                to: PortAt {
                    component: c.to.component,
                    port: c.to.port,
                },
                line: c.line,
            })
            .collect(),
    }
}

fn info_image(info: &ComponentInfo) -> InfoImage {
    let ports = |ports: &[PortDecl]| {
        ports
            .iter()
            .map(|p| PortImage {
                name: p.name.to_owned(),
                ty: p.ty,
            })
            .collect()
    };
    InfoImage {
        type_name: info.type_name.to_owned(),
        doc: info.doc.to_owned(),
        inputs: ports(&info.inputs),
        outputs: ports(&info.outputs),
        params: info
            .params
            .iter()
            .map(|p| ParamDeclImage {
                name: p.name.to_owned(),
                ty: p.ty,
                default: p.default.clone(),
            })
            .collect(),
    }
}

fn spec_of(image: GridImage) -> GridSpec {
    GridSpec {
        base_period: Duration::from_nanos(image.base_period_ns),
        cpus: image.cpus,
        priority: image.priority,
        mlock: image.mlock,
        line: image.line,
        timing: GridTiming {
            clock: image.clock,
            track_ticks: image.track_ticks,
            spin_us: image.spin_us,
        },
        assembly: image.assembly.map(|a| Assembly {
            name: a.name,
            generation: a.generation,
            base: a.base,
            source: None,
        }),
        declared: image
            .declared
            .into_iter()
            .map(|d| DeclaredType {
                info: info_of(d.info),
                program: d.program,
                line: d.line,
            })
            .collect(),
        components: image
            .components
            .into_iter()
            .map(|c| ComponentSpec {
                name: c.name,
                type_name: c.type_name,
                program: c.program,
                host: c.host,
                period: c.period,
                params: c.params.into_iter().collect::<Params>(),
                policy: c.policy,
                info: info_of(c.info),
                line: c.line,
            })
            .collect(),
        connections: image
            .connections
            .into_iter()
            .map(|c| Connection {
                from: PortRef {
                    component: c.from.component,
                    port: c.from.port,
                },
                to: PortRef {
                    component: c.to.component,
                    port: c.to.port,
                },
                line: c.line,
            })
            .collect(),
    }
}

fn info_of(info: InfoImage) -> ComponentInfo {
    let ports = |ports: Vec<PortImage>| {
        ports
            .into_iter()
            .map(|p| PortDecl::new(intern(&p.name), p.ty))
            .collect()
    };
    ComponentInfo {
        type_name: intern(&info.type_name),
        doc: intern(&info.doc),
        inputs: ports(info.inputs),
        outputs: ports(info.outputs),
        params: info
            .params
            .into_iter()
            .map(|p| ParamDecl {
                name: intern(&p.name),
                ty: p.ty,
                default: p.default,
            })
            .collect(),
    }
}
