//! A release's values to and from a running FMU: every value of a [`Values`] set or got, one
//! FMI call per FMI type, FMI 2.0 and 3.0 alike (FMI 2's Boolean travels as an int, in chunks
//! of a buffer on the stack: nothing is allocated).

use fmi::fmi2::instance::InstanceCS as Cs2;
use fmi::fmi3::instance::InstanceCS as Cs3;
use fmi::fmi3::GetSet;

use super::call::CallError;
use super::values::Values;

/// FMI 2 Booleans moved per call.
const CHUNK: usize = 64;

/// Sets every value of `v` on an FMI 2 instance.
pub fn set2(instance: &mut Cs2, v: &Values) -> Result<(), CallError> {
    use fmi::fmi2::instance::Common;
    let fmi2 = |call| move |e| CallError::fmi2(call, &e);
    if !v.real.refs.is_empty() {
        instance
            .set_real(&v.real.refs, &v.real.values)
            .map_err(fmi2("fmi2SetReal"))?;
    }
    if !v.int32.refs.is_empty() {
        instance
            .set_integer(&v.int32.refs, &v.int32.values)
            .map_err(fmi2("fmi2SetInteger"))?;
    }
    if !v.boolean.refs.is_empty() {
        let mut ints = [0i32; CHUNK];
        for (refs, values) in v
            .boolean
            .refs
            .chunks(CHUNK)
            .zip(v.boolean.values.chunks(CHUNK))
        {
            for (i, b) in values.iter().enumerate() {
                ints[i] = i32::from(*b);
            }
            instance
                .set_boolean(refs, &ints[..values.len()])
                .map_err(fmi2("fmi2SetBoolean"))?;
        }
    }
    Ok(())
}

/// Sets every value of `v` on an FMI 3 instance.
pub fn set3(instance: &mut Cs3, v: &Values) -> Result<(), CallError> {
    let fmi3 = |call| move |e| CallError::fmi3(call, &e);
    if !v.real.refs.is_empty() {
        instance
            .set_float64(&v.real.refs, &v.real.values)
            .map_err(fmi3("fmi3SetFloat64"))?;
    }
    if !v.int32.refs.is_empty() {
        instance
            .set_int32(&v.int32.refs, &v.int32.values)
            .map_err(fmi3("fmi3SetInt32"))?;
    }
    if !v.int64.refs.is_empty() {
        instance
            .set_int64(&v.int64.refs, &v.int64.values)
            .map_err(fmi3("fmi3SetInt64"))?;
    }
    if !v.boolean.refs.is_empty() {
        instance
            .set_boolean(&v.boolean.refs, &v.boolean.values)
            .map_err(fmi3("fmi3SetBoolean"))?;
    }
    Ok(())
}

/// Gets every value of `v` from an FMI 2 instance.
pub fn get2(instance: &mut Cs2, v: &mut Values) -> Result<(), CallError> {
    use fmi::fmi2::instance::Common;
    let fmi2 = |call| move |e| CallError::fmi2(call, &e);
    if !v.real.refs.is_empty() {
        instance
            .get_real(&v.real.refs, &mut v.real.values)
            .map_err(fmi2("fmi2GetReal"))?;
    }
    if !v.int32.refs.is_empty() {
        instance
            .get_integer(&v.int32.refs, &mut v.int32.values)
            .map_err(fmi2("fmi2GetInteger"))?;
    }
    if !v.boolean.refs.is_empty() {
        let mut ints = [0i32; CHUNK];
        for (refs, values) in v
            .boolean
            .refs
            .chunks(CHUNK)
            .zip(v.boolean.values.chunks_mut(CHUNK))
        {
            instance
                .get_boolean(refs, &mut ints[..values.len()])
                .map_err(fmi2("fmi2GetBoolean"))?;
            for (b, i) in values.iter_mut().zip(ints) {
                *b = i != 0;
            }
        }
    }
    Ok(())
}

/// Gets every value of `v` from an FMI 3 instance.
pub fn get3(instance: &mut Cs3, v: &mut Values) -> Result<(), CallError> {
    let fmi3 = |call| move |e| CallError::fmi3(call, &e);
    if !v.real.refs.is_empty() {
        instance
            .get_float64(&v.real.refs, &mut v.real.values)
            .map_err(fmi3("fmi3GetFloat64"))?;
    }
    if !v.int32.refs.is_empty() {
        instance
            .get_int32(&v.int32.refs, &mut v.int32.values)
            .map_err(fmi3("fmi3GetInt32"))?;
    }
    if !v.int64.refs.is_empty() {
        instance
            .get_int64(&v.int64.refs, &mut v.int64.values)
            .map_err(fmi3("fmi3GetInt64"))?;
    }
    if !v.boolean.refs.is_empty() {
        instance
            .get_boolean(&v.boolean.refs, &mut v.boolean.values)
            .map_err(fmi3("fmi3GetBoolean"))?;
    }
    Ok(())
}
