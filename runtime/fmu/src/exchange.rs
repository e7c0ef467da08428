//! A release's values to and from a running FMU: every value of a [`Values`] set or got, one
//! FMI call per FMI type, FMI 2.0 and 3.0 alike (FMI 2's Boolean travels as an int, in chunks
//! of a buffer on the stack: nothing is allocated).
//!
//! Which call moves which type is said once per version and type ([`Exchanged`]); what a
//! release does with a [`Typed`] buffer — no call when it is empty — is said once ([`put`],
//! [`take`]).

use fmi::fmi2::instance::Common as _;
use fmi::fmi2::instance::InstanceCS as Cs2;
use fmi::fmi3::instance::InstanceCS as Cs3;
use fmi::fmi3::GetSet as _;

use super::call::CallError;
use super::values::{Typed, Values};

/// FMI 2 Booleans moved per call.
const CHUNK: usize = 64;

/// Sets every value of `v` on an FMI 2 instance.
pub fn set2(instance: &mut Cs2, v: &Values) -> Result<(), CallError> {
    put(instance, &v.real)?;
    put(instance, &v.int32)?;
    put(instance, &v.boolean)
}

/// Sets every value of `v` on an FMI 3 instance.
pub fn set3(instance: &mut Cs3, v: &Values) -> Result<(), CallError> {
    put(instance, &v.real)?;
    put(instance, &v.int32)?;
    put(instance, &v.int64)?;
    put(instance, &v.boolean)
}

/// Gets every value of `v` from an FMI 2 instance.
pub fn get2(instance: &mut Cs2, v: &mut Values) -> Result<(), CallError> {
    take(instance, &mut v.real)?;
    take(instance, &mut v.int32)?;
    take(instance, &mut v.boolean)
}

/// Gets every value of `v` from an FMI 3 instance.
pub fn get3(instance: &mut Cs3, v: &mut Values) -> Result<(), CallError> {
    take(instance, &mut v.real)?;
    take(instance, &mut v.int32)?;
    take(instance, &mut v.int64)?;
    take(instance, &mut v.boolean)
}

/// Sets the values of `typed` on `instance`; no call when it has none.
fn put<I, T: Exchanged<I>>(instance: &mut I, typed: &Typed<T>) -> Result<(), CallError> {
    if typed.refs.is_empty() {
        return Ok(());
    }
    T::set(instance, &typed.refs, &typed.values)
}

/// Gets the values of `typed` from `instance`; no call when it has none.
fn take<I, T: Exchanged<I>>(instance: &mut I, typed: &mut Typed<T>) -> Result<(), CallError> {
    if typed.refs.is_empty() {
        return Ok(());
    }
    T::get(instance, &typed.refs, &mut typed.values)
}

/// A value type that an FMU instance of type `I` sets and gets: the FMI calls, a failure
/// named after the call.
trait Exchanged<I>: Sized {
    /// Sets `values` at `refs` (as many).
    fn set(instance: &mut I, refs: &[u32], values: &[Self]) -> Result<(), CallError>;
    /// Gets the values at `refs` into `values` (as many).
    fn get(instance: &mut I, refs: &[u32], values: &mut [Self]) -> Result<(), CallError>;
}

/// `impl Exchanged<I> for T` for each instance type `I` and value type `T` of the table: one
/// FMI call each way, its status mapped by `I`'s error constructor ([`CallError::fmi2`] or
/// [`CallError::fmi3`]). A macro, as the calls differ by name only.
macro_rules! exchanged {
    ($($instance:ty => $error:path {
        $($ty:ty: $set:ident $set_name:literal, $get:ident $get_name:literal;)*
    })*) => {$($(
        impl Exchanged<$instance> for $ty {
            fn set(i: &mut $instance, refs: &[u32], values: &[$ty]) -> Result<(), CallError> {
                i.$set(refs, values).map(drop).map_err(|e| $error($set_name, &e))
            }

            fn get(i: &mut $instance, refs: &[u32], values: &mut [$ty]) -> Result<(), CallError> {
                i.$get(refs, values).map(drop).map_err(|e| $error($get_name, &e))
            }
        }
    )*)*};
}

exchanged! {
    Cs2 => CallError::fmi2 {
        f64: set_real "fmi2SetReal", get_real "fmi2GetReal";
        i32: set_integer "fmi2SetInteger", get_integer "fmi2GetInteger";
    }
    Cs3 => CallError::fmi3 {
        f64: set_float64 "fmi3SetFloat64", get_float64 "fmi3GetFloat64";
        i32: set_int32 "fmi3SetInt32", get_int32 "fmi3GetInt32";
        i64: set_int64 "fmi3SetInt64", get_int64 "fmi3GetInt64";
        bool: set_boolean "fmi3SetBoolean", get_boolean "fmi3GetBoolean";
    }
}

/// FMI 2's Boolean is an int: converted through a buffer on the stack, [`CHUNK`] values a call.
impl Exchanged<Cs2> for bool {
    fn set(instance: &mut Cs2, refs: &[u32], values: &[bool]) -> Result<(), CallError> {
        let mut ints = [0i32; CHUNK];
        for (refs, values) in refs.chunks(CHUNK).zip(values.chunks(CHUNK)) {
            for (i, b) in ints.iter_mut().zip(values) {
                *i = i32::from(*b);
            }
            instance
                .set_boolean(refs, &ints[..values.len()])
                .map_err(|e| CallError::fmi2("fmi2SetBoolean", &e))?;
        }
        Ok(())
    }

    fn get(instance: &mut Cs2, refs: &[u32], values: &mut [bool]) -> Result<(), CallError> {
        let mut ints = [0i32; CHUNK];
        for (refs, values) in refs.chunks(CHUNK).zip(values.chunks_mut(CHUNK)) {
            instance
                .get_boolean(refs, &mut ints[..values.len()])
                .map_err(|e| CallError::fmi2("fmi2GetBoolean", &e))?;
            for (b, i) in values.iter_mut().zip(ints) {
                *b = i != 0;
            }
        }
        Ok(())
    }
}
