//! Bulk decoding of fixed-size binary records: one monomorphised loop per (type, endianness),
//! chosen once per column, so the per-point work is a few loads and conversions.

use rayon::prelude::*;

use super::PlyScalarType;

/// Blocks at least this large are decoded on the rayon pool. Below it (about 20k points of
/// `x y z` floats) thread hand-off costs more than it saves.
const PAR_MIN_BYTES: usize = 256 * 1024;

/// `N` bytes at `off` in `rec`, or zeros if out of range (never the case for the offsets the
/// reader computes from the header; this keeps the hot loop panic-free).
#[inline(always)]
fn bytes<const N: usize>(rec: &[u8], off: usize) -> [u8; N] {
    rec.get(off..)
        .and_then(|s| s.first_chunk::<N>())
        .copied()
        .unwrap_or([0; N])
}

/// A scalar type with a fixed byte order.
pub(crate) trait Decode {
    fn get(rec: &[u8], off: usize) -> f64;
}

macro_rules! decoders {
    ($($name:ident: $t:ty, $n:literal, $from:ident;)*) => {$(
        pub(crate) struct $name;
        impl Decode for $name {
            #[inline(always)]
            fn get(rec: &[u8], off: usize) -> f64 {
                f64::from(<$t>::$from(bytes::<$n>(rec, off)))
            }
        }
    )*};
}

decoders! {
    I8: i8, 1, from_le_bytes;
    U8: u8, 1, from_le_bytes;
    I16Le: i16, 2, from_le_bytes;
    I16Be: i16, 2, from_be_bytes;
    U16Le: u16, 2, from_le_bytes;
    U16Be: u16, 2, from_be_bytes;
    I32Le: i32, 4, from_le_bytes;
    I32Be: i32, 4, from_be_bytes;
    U32Le: u32, 4, from_le_bytes;
    U32Be: u32, 4, from_be_bytes;
    F32Le: f32, 4, from_le_bytes;
    F32Be: f32, 4, from_be_bytes;
    F64Le: f64, 8, from_le_bytes;
    F64Be: f64, 8, from_be_bytes;
}

/// Reads one scalar of type `ty` at `off` (the dynamic path, for irregular layouts).
#[inline]
pub(crate) fn read_dyn(ty: PlyScalarType, big: bool, rec: &[u8], off: usize) -> f64 {
    use PlyScalarType as T;
    match (ty, big) {
        (T::Char, _) => I8::get(rec, off),
        (T::UChar, _) => U8::get(rec, off),
        (T::Short, false) => I16Le::get(rec, off),
        (T::Short, true) => I16Be::get(rec, off),
        (T::UShort, false) => U16Le::get(rec, off),
        (T::UShort, true) => U16Be::get(rec, off),
        (T::Int, false) => I32Le::get(rec, off),
        (T::Int, true) => I32Be::get(rec, off),
        (T::UInt, false) => U32Le::get(rec, off),
        (T::UInt, true) => U32Be::get(rec, off),
        (T::Float, false) => F32Le::get(rec, off),
        (T::Float, true) => F32Be::get(rec, off),
        (T::Double, false) => F64Le::get(rec, off),
        (T::Double, true) => F64Be::get(rec, off),
    }
}

fn decode_static<D: Decode, T: Send, const N: usize, F>(
    block: &[u8],
    stride: usize,
    offs: [usize; N],
    f: &F,
) -> Vec<T>
where
    F: Fn([f64; N]) -> T + Sync,
{
    let one = |rec: &[u8]| f(offs.map(|o| D::get(rec, o)));
    if block.len() >= PAR_MIN_BYTES {
        block.par_chunks_exact(stride).map(one).collect()
    } else {
        block.chunks_exact(stride).map(one).collect()
    }
}

/// Decodes `N` properties of every `stride`-byte record of `block` and maps them through `f`.
///
/// `props` holds the byte offset within the record and the type of each property. When all `N`
/// share one type (the usual case) a specialised loop is used; otherwise each value is read
/// through [`read_dyn`].
pub(crate) fn decode_column<T: Send, const N: usize, F>(
    block: &[u8],
    stride: usize,
    props: [(usize, PlyScalarType); N],
    big: bool,
    f: F,
) -> Vec<T>
where
    F: Fn([f64; N]) -> T + Sync,
{
    if stride == 0 {
        return Vec::new();
    }
    let offs = props.map(|(o, _)| o);
    let Some(&(_, ty)) = props.first() else {
        return block.chunks_exact(stride).map(|_| f([0.0; N])).collect();
    };
    if props.iter().any(|&(_, t)| t != ty) {
        let one = |rec: &[u8]| f(props.map(|(o, t)| read_dyn(t, big, rec, o)));
        return block.chunks_exact(stride).map(one).collect();
    }
    use PlyScalarType as S;
    match (ty, big) {
        (S::Char, _) => decode_static::<I8, _, N, _>(block, stride, offs, &f),
        (S::UChar, _) => decode_static::<U8, _, N, _>(block, stride, offs, &f),
        (S::Short, false) => decode_static::<I16Le, _, N, _>(block, stride, offs, &f),
        (S::Short, true) => decode_static::<I16Be, _, N, _>(block, stride, offs, &f),
        (S::UShort, false) => decode_static::<U16Le, _, N, _>(block, stride, offs, &f),
        (S::UShort, true) => decode_static::<U16Be, _, N, _>(block, stride, offs, &f),
        (S::Int, false) => decode_static::<I32Le, _, N, _>(block, stride, offs, &f),
        (S::Int, true) => decode_static::<I32Be, _, N, _>(block, stride, offs, &f),
        (S::UInt, false) => decode_static::<U32Le, _, N, _>(block, stride, offs, &f),
        (S::UInt, true) => decode_static::<U32Be, _, N, _>(block, stride, offs, &f),
        (S::Float, false) => decode_static::<F32Le, _, N, _>(block, stride, offs, &f),
        (S::Float, true) => decode_static::<F32Be, _, N, _>(block, stride, offs, &f),
        (S::Double, false) => decode_static::<F64Le, _, N, _>(block, stride, offs, &f),
        (S::Double, true) => decode_static::<F64Be, _, N, _>(block, stride, offs, &f),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_type_both_endians() {
        use PlyScalarType as S;
        // Each value is exactly representable in its type, so the decoded f64 must be exact.
        let cases: Vec<(S, Vec<u8>, Vec<u8>, f64)> = vec![
            (S::Char, vec![0xfe], vec![0xfe], -2.0),
            (S::UChar, vec![0xfe], vec![0xfe], 254.0),
            (
                S::Short,
                (-300i16).to_le_bytes().to_vec(),
                (-300i16).to_be_bytes().to_vec(),
                -300.0,
            ),
            (
                S::UShort,
                60000u16.to_le_bytes().to_vec(),
                60000u16.to_be_bytes().to_vec(),
                60000.0,
            ),
            (
                S::Int,
                (-70000i32).to_le_bytes().to_vec(),
                (-70000i32).to_be_bytes().to_vec(),
                -70000.0,
            ),
            (
                S::UInt,
                4_000_000_000u32.to_le_bytes().to_vec(),
                4_000_000_000u32.to_be_bytes().to_vec(),
                4e9,
            ),
            (
                S::Float,
                1.5f32.to_le_bytes().to_vec(),
                1.5f32.to_be_bytes().to_vec(),
                1.5,
            ),
            (
                S::Double,
                (-0.1f64).to_le_bytes().to_vec(),
                (-0.1f64).to_be_bytes().to_vec(),
                -0.1,
            ),
        ];
        for (ty, le, be, want) in cases {
            assert_eq!(le.len(), ty.size());
            assert_eq!(read_dyn(ty, false, &le, 0), want, "{ty:?} LE");
            assert_eq!(read_dyn(ty, true, &be, 0), want, "{ty:?} BE");
            let col = decode_column(&le, ty.size(), [(0, ty)], false, |[v]| v);
            assert_eq!(col, vec![want]);
            let col = decode_column(&be, ty.size(), [(0, ty)], true, |[v]| v);
            assert_eq!(col, vec![want]);
        }
    }

    #[test]
    fn mixed_types_use_the_dynamic_path() {
        let mut rec = Vec::new();
        rec.extend_from_slice(&2.5f32.to_le_bytes());
        rec.extend_from_slice(&(-4.25f64).to_le_bytes());
        rec.push(7);
        let block = [rec.clone(), rec].concat();
        let col = decode_column(
            &block,
            13,
            [
                (0, PlyScalarType::Float),
                (4, PlyScalarType::Double),
                (12, PlyScalarType::UChar),
            ],
            false,
            |v| v,
        );
        assert_eq!(col, vec![[2.5, -4.25, 7.0]; 2]);
        // A ragged tail is ignored (the caller checks sizes), out-of-range offsets read zeros.
        assert_eq!(
            decode_column(
                &block[..20],
                13,
                [(20, PlyScalarType::Float)],
                false,
                |[v]| v
            ),
            vec![0.0]
        );
    }
}
