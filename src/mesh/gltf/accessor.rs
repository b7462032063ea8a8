//! Reading accessors with every offset checked before any slice is taken: the `gltf` crate
//! validates the document's references (an accessor's buffer view exists, and so on), not
//! whether the byte ranges they name lie inside the buffers. Here every range is computed
//! in `u64` with checked arithmetic and compared with the bytes actually present, so a lying
//! count, offset or stride is an error naming the accessor, and no vector is ever longer than
//! what the buffer holds.

use gltf::accessor::{DataType, Dimensions};

/// The buffers' bytes, by buffer index.
pub type Buffers = [Vec<u8>];

/// What one accessor's elements are, and where they lie.
struct Layout<'b> {
    bytes: &'b [u8],
    start: usize,
    stride: usize,
    count: usize,
}

impl Layout<'_> {
    fn element(&self, i: usize) -> &[u8] {
        &self.bytes[self.start + i * self.stride..]
    }
}

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

fn dimension_count(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 | Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

/// Checks an accessor's range against its buffer view and buffer.
fn layout<'b>(a: &gltf::Accessor, buffers: &'b Buffers) -> Result<Layout<'b>, String> {
    if a.sparse().is_some() {
        return Err("sparse accessors are not supported".into());
    }
    let view = a
        .view()
        .ok_or("an accessor without a buffer view (all zeros) is not supported")?;
    let bytes = buffers
        .get(view.buffer().index())
        .ok_or("its buffer was not loaded")?;
    let element = component_size(a.data_type()) * dimension_count(a.dimensions());
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "byteStride {stride} is smaller than one element ({element} bytes)"
        ));
    }
    let count = a.count();
    if count == 0 {
        return Err("count is 0".into());
    }
    let view_end = (view.offset() as u64)
        .checked_add(view.length() as u64)
        .filter(|&end| end <= bytes.len() as u64)
        .ok_or_else(|| {
            format!(
                "buffer view {} (offset {}, length {}) lies outside its buffer of {} bytes",
                view.index(),
                view.offset(),
                view.length(),
                bytes.len()
            )
        })?;
    let start = view.offset() as u64 + a.offset() as u64;
    let end = (count as u64 - 1)
        .checked_mul(stride as u64)
        .and_then(|span| span.checked_add(start))
        .and_then(|last| last.checked_add(element as u64));
    match end {
        Some(end) if end <= view_end => Ok(Layout {
            bytes,
            start: start as usize,
            stride,
            count,
        }),
        _ => Err(format!(
            "{count} elements of {element} bytes (stride {stride}) from byte {start} run past the end of buffer view {} ({view_end})",
            view.index()
        )),
    }
}

fn f32_at(b: &[u8], k: usize) -> f32 {
    f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
}

fn expect(
    a: &gltf::Accessor,
    types: &[DataType],
    dims: Dimensions,
    what: &str,
) -> Result<(), String> {
    if types.contains(&a.data_type()) && a.dimensions() == dims {
        Ok(())
    } else {
        Err(format!(
            "{what} as {:?} {:?} is not supported (expected {dims:?} of {types:?})",
            a.dimensions(),
            a.data_type()
        ))
    }
}

/// A `VEC3` of `FLOAT` (positions, normals).
pub fn read_vec3(
    a: &gltf::Accessor,
    buffers: &Buffers,
    what: &str,
) -> Result<Vec<[f32; 3]>, String> {
    expect(a, &[DataType::F32], Dimensions::Vec3, what)?;
    let l = layout(a, buffers)?;
    Ok((0..l.count)
        .map(|i| {
            let e = l.element(i);
            [f32_at(e, 0), f32_at(e, 1), f32_at(e, 2)]
        })
        .collect())
}

/// Texture coordinates: `VEC2` of `FLOAT`, or of normalised unsigned bytes or shorts.
pub fn read_texcoords(a: &gltf::Accessor, buffers: &Buffers) -> Result<Vec<[f32; 2]>, String> {
    let types = [DataType::F32, DataType::U8, DataType::U16];
    expect(a, &types, Dimensions::Vec2, "TEXCOORD_0")?;
    if a.data_type() != DataType::F32 && !a.normalized() {
        return Err("TEXCOORD_0 of integers must be normalized".into());
    }
    let l = layout(a, buffers)?;
    let value = |e: &[u8], k: usize| match a.data_type() {
        DataType::U8 => f32::from(e[k]) / 255.0,
        DataType::U16 => f32::from(u16::from_le_bytes([e[2 * k], e[2 * k + 1]])) / 65535.0,
        _ => f32_at(e, k),
    };
    Ok((0..l.count)
        .map(|i| {
            let e = l.element(i);
            [value(e, 0), value(e, 1)]
        })
        .collect())
}

/// Indices: `SCALAR` of unsigned bytes, shorts or ints.
pub fn read_indices(a: &gltf::Accessor, buffers: &Buffers) -> Result<Vec<u32>, String> {
    let types = [DataType::U8, DataType::U16, DataType::U32];
    expect(a, &types, Dimensions::Scalar, "indices")?;
    let l = layout(a, buffers)?;
    Ok((0..l.count)
        .map(|i| {
            let e = l.element(i);
            match a.data_type() {
                DataType::U8 => u32::from(e[0]),
                DataType::U16 => u32::from(u16::from_le_bytes([e[0], e[1]])),
                _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
            }
        })
        .collect())
}

/// The bytes of a buffer view (an embedded image), checked against its buffer.
pub fn view_bytes<'b>(view: &gltf::buffer::View, buffers: &'b Buffers) -> Result<&'b [u8], String> {
    let bytes = buffers
        .get(view.buffer().index())
        .ok_or("its buffer was not loaded")?;
    let end = (view.offset() as u64).checked_add(view.length() as u64);
    match end {
        Some(end) if end <= bytes.len() as u64 => Ok(&bytes[view.offset()..end as usize]),
        _ => Err(format!(
            "buffer view {} (offset {}, length {}) lies outside its buffer of {} bytes",
            view.index(),
            view.offset(),
            view.length(),
            bytes.len()
        )),
    }
}
