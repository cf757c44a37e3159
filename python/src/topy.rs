//! Results handed to Python as Python objects built straight from their serde form, with the
//! shapes `json.loads` would give for the CLI's `--json` text (same keys in the same order,
//! same numbers to the bit), but without writing that text and parsing it again.
//!
//! The mapping follows `serde_json`'s: a struct or map becomes a `dict` (keys in serialisation
//! order), a sequence or tuple a `list`, an integer an `int`, an `f64` a `float` (NaN and the
//! infinities become `None`, as `serde_json` writes `null`), an `f32` the `float` of its shortest
//! decimal (what parsing `serde_json`'s text gives), `None` and `()` become `None`, a unit variant
//! its name, a newtype, tuple or struct variant `{name: value}`, bytes a list of `int`s. Map keys
//! must be strings, or integers, `bool`s or `char`s (written as strings, as `serde_json` does);
//! other keys are refused (no tribo result has them).

use std::cell::RefCell;
use std::collections::HashMap;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyList, PyString};
use pyo3::IntoPyObjectExt;
use serde::ser::{self, Serialize};

/// Why a value could not be handed to Python.
#[derive(Debug, thiserror::Error)]
pub enum ToPyError {
    /// The value's `Serialize` reported an error, or it has a shape Python cannot receive.
    #[error("{0}")]
    Shape(String),
    /// Python refused to build an object (out of memory, say).
    #[error("{0}")]
    Python(#[from] PyErr),
}

impl ser::Error for ToPyError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        ToPyError::Shape(msg.to_string())
    }
}

impl From<ToPyError> for PyErr {
    fn from(e: ToPyError) -> Self {
        match e {
            ToPyError::Python(e) => e,
            ToPyError::Shape(m) => PyValueError::new_err(m),
        }
    }
}

/// `value` as Python objects (see the module's documentation for the mapping).
pub fn to_py<'py, T: Serialize + ?Sized>(
    py: Python<'py>,
    value: &T,
) -> Result<Bound<'py, PyAny>, ToPyError> {
    let names = Names::default();
    value.serialize(Builder { py, names: &names })
}

/// The field and variant names met in one conversion, each made a Python string once: a result
/// repeats the same few names hundreds of times, and a string already made has its hash cached,
/// so each later dict insertion skips both the decoding and the hashing (`json.loads` keeps
/// such a memo of keys for the same reason). Names are `&'static str`, known by their address.
#[derive(Default)]
struct Names<'py> {
    made: RefCell<HashMap<(usize, usize), Bound<'py, PyString>>>,
}

impl<'py> Names<'py> {
    /// The Python string for the name `name`.
    fn get(&self, py: Python<'py>, name: &'static str) -> Bound<'py, PyString> {
        let key = (name.as_ptr() as usize, name.len());
        self.made
            .borrow_mut()
            .entry(key)
            .or_insert_with(|| PyString::new(py, name))
            .clone()
    }
}

/// The serde serializer whose output is a Python object.
#[derive(Clone, Copy)]
struct Builder<'a, 'py> {
    py: Python<'py>,
    names: &'a Names<'py>,
}

impl<'a, 'py> Builder<'a, 'py> {
    /// `value` through this builder (its names memo kept).
    fn build<T: Serialize + ?Sized>(self, value: &T) -> Result<Bound<'py, PyAny>, ToPyError> {
        value.serialize(self)
    }

    /// `{variant: value}`, the form of a non-unit enum variant.
    fn tagged(
        self,
        variant: &'static str,
        value: Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyAny>, ToPyError> {
        let dict = PyDict::new(self.py);
        dict.set_item(self.names.get(self.py, variant), value)?;
        Ok(dict.into_any())
    }

    /// A Rust integer as a Python `int`.
    fn int<I: IntoPyObject<'py>>(self, v: I) -> Result<Bound<'py, PyAny>, ToPyError> {
        Ok(v.into_bound_py_any(self.py)?)
    }
}

/// A list being built: its items so far, and the variant name for a tuple variant.
struct ListBuilder<'a, 'py> {
    b: Builder<'a, 'py>,
    items: Vec<Bound<'py, PyAny>>,
    variant: Option<&'static str>,
}

impl<'a, 'py> ListBuilder<'a, 'py> {
    fn push<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), ToPyError> {
        self.items.push(self.b.build(value)?);
        Ok(())
    }

    fn finish(self) -> Result<Bound<'py, PyAny>, ToPyError> {
        let list = PyList::new(self.b.py, self.items)?.into_any();
        match self.variant {
            Some(v) => self.b.tagged(v, list),
            None => Ok(list),
        }
    }
}

/// A dict being built: the dict, the key waiting for its value (maps), and the variant name for
/// a struct variant.
struct DictBuilder<'a, 'py> {
    b: Builder<'a, 'py>,
    dict: Bound<'py, PyDict>,
    key: Option<Bound<'py, PyString>>,
    variant: Option<&'static str>,
}

impl<'a, 'py> DictBuilder<'a, 'py> {
    fn new(b: Builder<'a, 'py>, variant: Option<&'static str>) -> Self {
        Self {
            b,
            dict: PyDict::new(b.py),
            key: None,
            variant,
        }
    }

    fn field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), ToPyError> {
        let value = self.b.build(value)?;
        self.dict
            .set_item(self.b.names.get(self.b.py, key), value)?;
        Ok(())
    }

    fn finish(self) -> Result<Bound<'py, PyAny>, ToPyError> {
        let dict = self.dict.into_any();
        match self.variant {
            Some(v) => self.b.tagged(v, dict),
            None => Ok(dict),
        }
    }
}

impl<'a, 'py> ser::Serializer for Builder<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = ToPyError;
    type SerializeSeq = ListBuilder<'a, 'py>;
    type SerializeTuple = ListBuilder<'a, 'py>;
    type SerializeTupleStruct = ListBuilder<'a, 'py>;
    type SerializeTupleVariant = ListBuilder<'a, 'py>;
    type SerializeMap = DictBuilder<'a, 'py>;
    type SerializeStruct = DictBuilder<'a, 'py>;
    type SerializeStructVariant = DictBuilder<'a, 'py>;

    fn serialize_bool(self, v: bool) -> Result<Self::Ok, Self::Error> {
        Ok(PyBool::new(self.py, v).to_owned().into_any())
    }
    fn serialize_i8(self, v: i8) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_i16(self, v: i16) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_i32(self, v: i32) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_i64(self, v: i64) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_i128(self, v: i128) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_u8(self, v: u8) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_u16(self, v: u16) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_u32(self, v: u32) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_u64(self, v: u64) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_u128(self, v: u128) -> Result<Self::Ok, Self::Error> {
        self.int(v)
    }
    fn serialize_f32(self, v: f32) -> Result<Self::Ok, Self::Error> {
        // serde_json writes an f32 as its shortest decimal, which Python reads as an f64; the
        // same decimal through Rust's shortest Display gives the same f64.
        if !v.is_finite() {
            return self.serialize_unit();
        }
        let wide: f64 = v
            .to_string()
            .parse()
            .map_err(|e| ToPyError::Shape(format!("the f32 {v} has no f64 form: {e}")))?;
        self.serialize_f64(wide)
    }
    fn serialize_f64(self, v: f64) -> Result<Self::Ok, Self::Error> {
        if v.is_finite() {
            Ok(PyFloat::new(self.py, v).into_any())
        } else {
            self.serialize_unit()
        }
    }
    fn serialize_char(self, v: char) -> Result<Self::Ok, Self::Error> {
        self.serialize_str(v.encode_utf8(&mut [0; 4]))
    }
    fn serialize_str(self, v: &str) -> Result<Self::Ok, Self::Error> {
        Ok(PyString::new(self.py, v).into_any())
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<Self::Ok, Self::Error> {
        Ok(PyList::new(self.py, v)?.into_any())
    }
    fn serialize_none(self) -> Result<Self::Ok, Self::Error> {
        self.serialize_unit()
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<Self::Ok, Self::Error> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<Self::Ok, Self::Error> {
        Ok(self.py.None().into_bound(self.py))
    }
    fn serialize_unit_struct(self, _name: &'static str) -> Result<Self::Ok, Self::Error> {
        self.serialize_unit()
    }
    fn serialize_unit_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
    ) -> Result<Self::Ok, Self::Error> {
        Ok(self.names.get(self.py, variant).into_any())
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        value: &T,
    ) -> Result<Self::Ok, Self::Error> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<Self::Ok, Self::Error> {
        let inner = self.build(value)?;
        self.tagged(variant, inner)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Self::SerializeSeq, Self::Error> {
        Ok(ListBuilder {
            b: self,
            items: Vec::with_capacity(len.unwrap_or(0)),
            variant: None,
        })
    }
    fn serialize_tuple(self, len: usize) -> Result<Self::SerializeTuple, Self::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(
        self,
        _name: &'static str,
        len: usize,
    ) -> Result<Self::SerializeTupleStruct, Self::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Self::SerializeTupleVariant, Self::Error> {
        Ok(ListBuilder {
            b: self,
            items: Vec::with_capacity(len),
            variant: Some(variant),
        })
    }
    fn serialize_map(self, _len: Option<usize>) -> Result<Self::SerializeMap, Self::Error> {
        Ok(DictBuilder::new(self, None))
    }
    fn serialize_struct(
        self,
        _name: &'static str,
        _len: usize,
    ) -> Result<Self::SerializeStruct, Self::Error> {
        Ok(DictBuilder::new(self, None))
    }
    fn serialize_struct_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        _len: usize,
    ) -> Result<Self::SerializeStructVariant, Self::Error> {
        Ok(DictBuilder::new(self, Some(variant)))
    }
}

/// serde's four sequence-like serializers (a list, a tuple, a tuple struct, a tuple variant)
/// all become a Python list: one body, written once.
macro_rules! list_serializer {
    ($($trait:ident :: $method:ident),+) => {$(
        impl<'a, 'py> ser::$trait for ListBuilder<'a, 'py> {
            type Ok = Bound<'py, PyAny>;
            type Error = ToPyError;
            fn $method<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Self::Error> {
                self.push(value)
            }
            fn end(self) -> Result<Self::Ok, Self::Error> {
                self.finish()
            }
        }
    )+};
}

list_serializer!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl<'a, 'py> ser::SerializeMap for DictBuilder<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = ToPyError;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Self::Error> {
        self.key = Some(map_key(self.b, key)?);
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Self::Error> {
        let key = self
            .key
            .take()
            .ok_or_else(|| ToPyError::Shape("a map value was given before its key".into()))?;
        self.dict.set_item(key, self.b.build(value)?)?;
        Ok(())
    }
    fn end(self) -> Result<Self::Ok, Self::Error> {
        self.finish()
    }
}

impl<'a, 'py> ser::SerializeStruct for DictBuilder<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = ToPyError;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Self::Error> {
        self.field(key, value)
    }
    fn end(self) -> Result<Self::Ok, Self::Error> {
        self.finish()
    }
}

impl<'a, 'py> ser::SerializeStructVariant for DictBuilder<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = ToPyError;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Self::Error> {
        self.field(key, value)
    }
    fn end(self) -> Result<Self::Ok, Self::Error> {
        self.finish()
    }
}

/// A map key as the string `serde_json` would write for it: a string as it is, an integer,
/// `bool` or `char` in its text form; anything else (a float, a sequence, ...) is refused.
fn map_key<'py, T: Serialize + ?Sized>(
    b: Builder<'_, 'py>,
    key: &T,
) -> Result<Bound<'py, PyString>, ToPyError> {
    let py = b.py;
    let object = b.build(key)?;
    if let Ok(s) = object.cast::<PyString>() {
        return Ok(s.clone());
    }
    if let Ok(b) = object.cast::<PyBool>() {
        return Ok(PyString::new(
            py,
            if b.is_true() { "true" } else { "false" },
        ));
    }
    if object.is_instance_of::<pyo3::types::PyInt>() {
        return Ok(object.str()?);
    }
    Err(ToPyError::Shape(format!(
        "a map key must be a string, an integer, a bool or a char, not a {}",
        object.get_type().name()?
    )))
}
