//! [`PointBatch`]: a columnar block of points. Readers yield batches, builders and writers consume
//! them. Each attribute of the [`Schema`] is one optional column; positions are always present and
//! in f64 world coordinates.

use crate::schema::{Attribute, Schema};

/// A LAS wave packet descriptor reference (formats 4, 5, 9, 10): 29 bytes on disk.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WavePacket {
    pub descriptor_index: u8,
    pub byte_offset: u64,
    pub size: u32,
    pub return_point_location: f32,
    pub x_t: f32,
    pub y_t: f32,
    pub z_t: f32,
}

/// One point's values, for readers that assemble points one at a time (PLY, PCD, text).
/// [`PointBatch::push_record`] stores the values whose column the batch has.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PointRecord {
    pub position: [f64; 3],
    pub intensity: u16,
    pub return_number: u8,
    pub number_of_returns: u8,
    pub classification: u8,
    pub scan_angle: f32,
    pub user_data: u8,
    pub point_source_id: u16,
    pub gps_time: f64,
    pub rgb: [u16; 3],
    pub normal: [f32; 3],
}

/// Fixed-size little-endian byte form of a column's element, for row records (spill files).
pub trait RowBytes: Copy {
    const SIZE: usize;
    fn put(&self, out: &mut Vec<u8>);
    fn get(b: &[u8]) -> Self;
    /// Writes the `SIZE` bytes `put` appends into `out[..SIZE]`.
    fn write(&self, out: &mut [u8]);
}

macro_rules! row_bytes_num {
    ($($t:ty),*) => {$(
        impl RowBytes for $t {
            const SIZE: usize = std::mem::size_of::<$t>();
            fn put(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn get(b: &[u8]) -> Self {
                <$t>::from_le_bytes(b[..Self::SIZE].try_into().unwrap())
            }
            fn write(&self, out: &mut [u8]) {
                out[..Self::SIZE].copy_from_slice(&self.to_le_bytes());
            }
        }
    )*};
}
row_bytes_num!(u8, u16, u32, u64, f32, f64);

impl<T: RowBytes + Default> RowBytes for [T; 3] {
    const SIZE: usize = 3 * T::SIZE;
    fn put(&self, out: &mut Vec<u8>) {
        self.iter().for_each(|v| v.put(out));
    }
    fn get(b: &[u8]) -> Self {
        std::array::from_fn(|k| T::get(&b[k * T::SIZE..]))
    }
    fn write(&self, out: &mut [u8]) {
        for (v, o) in self.iter().zip(out.chunks_exact_mut(T::SIZE)) {
            v.write(o);
        }
    }
}

impl RowBytes for WavePacket {
    const SIZE: usize = 29;
    fn put(&self, out: &mut Vec<u8>) {
        self.descriptor_index.put(out);
        self.byte_offset.put(out);
        self.size.put(out);
        for v in [self.return_point_location, self.x_t, self.y_t, self.z_t] {
            v.put(out);
        }
    }
    fn write(&self, out: &mut [u8]) {
        let mut v = Vec::with_capacity(Self::SIZE);
        self.put(&mut v);
        out[..Self::SIZE].copy_from_slice(&v);
    }
    fn get(b: &[u8]) -> Self {
        WavePacket {
            descriptor_index: b[0],
            byte_offset: u64::get(&b[1..]),
            size: u32::get(&b[9..]),
            return_point_location: f32::get(&b[13..]),
            x_t: f32::get(&b[17..]),
            y_t: f32::get(&b[21..]),
            z_t: f32::get(&b[25..]),
        }
    }
}

/// Calls `$m!(field, Type, Attribute)` for every optional column, so operations over all columns
/// are written once.
macro_rules! for_each_column {
    ($m:ident) => {
        $m!(intensity, u16, Intensity);
        $m!(return_number, u8, ReturnNumber);
        $m!(number_of_returns, u8, NumberOfReturns);
        $m!(classification, u8, Classification);
        $m!(classification_flags, u8, ClassificationFlags);
        $m!(scan_flags, u8, ScanFlags);
        $m!(scanner_channel, u8, ScannerChannel);
        $m!(scan_angle, f32, ScanAngle);
        $m!(user_data, u8, UserData);
        $m!(point_source_id, u16, PointSourceId);
        $m!(gps_time, f64, GpsTime);
        $m!(rgb, [u16; 3], Rgb);
        $m!(nir, u16, Nir);
        $m!(wave_packet, WavePacket, WavePacket);
        $m!(normal, [f32; 3], Normal);
    };
}

/// Columns of points. Bit layouts of the LAS flag columns:
/// `classification_flags`: bit 0 synthetic, 1 key point, 2 withheld, 3 overlap;
/// `scan_flags`: bit 0 scan direction, bit 1 edge of flight line.
/// `scan_angle` is in degrees. `extra_bytes` holds `extra_stride` raw bytes per point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointBatch {
    pub positions: Vec<[f64; 3]>,
    pub intensity: Option<Vec<u16>>,
    pub return_number: Option<Vec<u8>>,
    pub number_of_returns: Option<Vec<u8>>,
    pub classification: Option<Vec<u8>>,
    pub classification_flags: Option<Vec<u8>>,
    pub scan_flags: Option<Vec<u8>>,
    pub scanner_channel: Option<Vec<u8>>,
    pub scan_angle: Option<Vec<f32>>,
    pub user_data: Option<Vec<u8>>,
    pub point_source_id: Option<Vec<u16>>,
    pub gps_time: Option<Vec<f64>>,
    pub rgb: Option<Vec<[u16; 3]>>,
    pub nir: Option<Vec<u16>>,
    pub wave_packet: Option<Vec<WavePacket>>,
    pub normal: Option<Vec<[f32; 3]>>,
    pub extra_bytes: Option<Vec<u8>>,
    pub extra_stride: usize,
}

/// A column's value as numbers (three for colours and normals, seven for a wave packet), for
/// showing a point.
pub trait Numbers {
    fn numbers(&self) -> Vec<f64>;
}

macro_rules! scalar_numbers {
    ($($t:ty),*) => {$(
        impl Numbers for $t {
            fn numbers(&self) -> Vec<f64> {
                vec![*self as f64]
            }
        }
    )*};
}
scalar_numbers!(u8, u16, f32, f64);

impl Numbers for [u16; 3] {
    fn numbers(&self) -> Vec<f64> {
        self.iter().map(|&v| v as f64).collect()
    }
}

impl Numbers for [f32; 3] {
    fn numbers(&self) -> Vec<f64> {
        self.iter().map(|&v| v as f64).collect()
    }
}

impl Numbers for WavePacket {
    fn numbers(&self) -> Vec<f64> {
        vec![
            self.descriptor_index as f64,
            self.byte_offset as f64,
            self.size as f64,
            self.return_point_location as f64,
            self.x_t as f64,
            self.y_t as f64,
            self.z_t as f64,
        ]
    }
}

impl PointBatch {
    /// Every attribute of point `i` but its position, as numbers, in column order (what a
    /// viewer shows of a picked point).
    pub fn values(&self, i: usize) -> Vec<(Attribute, Vec<f64>)> {
        let mut out = Vec::new();
        macro_rules! one {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &self.$f {
                    out.push((Attribute::$a, c[i].numbers()));
                }
            };
        }
        for_each_column!(one);
        out
    }

    /// An empty batch with a column for every attribute of `schema`.
    pub fn with_schema(schema: &Schema, capacity: usize) -> PointBatch {
        let mut b = PointBatch {
            positions: Vec::with_capacity(capacity),
            ..Default::default()
        };
        macro_rules! init {
            ($f:ident, $t:ty, $a:ident) => {
                if schema.has(&Attribute::$a) {
                    b.$f = Some(Vec::with_capacity(capacity));
                }
            };
        }
        for_each_column!(init);
        if schema.extra_bytes > 0 {
            b.extra_stride = schema.extra_bytes;
            b.extra_bytes = Some(Vec::with_capacity(capacity * schema.extra_bytes));
        }
        b
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Appends one point; columns the record has no value for get their zero.
    pub fn push_record(&mut self, r: &PointRecord) {
        self.positions.push(r.position);
        macro_rules! put {
            ($($f:ident),*) => {$(
                if let Some(c) = &mut self.$f {
                    c.push(r.$f);
                }
            )*};
        }
        put!(
            intensity,
            return_number,
            number_of_returns,
            classification,
            scan_angle,
            user_data,
            point_source_id
        );
        put!(gps_time, rgb, normal);
        macro_rules! zero {
            ($($f:ident),*) => {$(
                if let Some(c) = &mut self.$f {
                    c.push(Default::default());
                }
            )*};
        }
        zero!(
            classification_flags,
            scan_flags,
            scanner_channel,
            nir,
            wave_packet
        );
        if let Some(e) = &mut self.extra_bytes {
            e.resize(e.len() + self.extra_stride, 0);
        }
    }
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Drops the columns `schema` does not name (a reader that decodes whole records, asked
    /// for some columns only); columns `schema` names that the batch lacks stay absent.
    pub fn keep_columns(&mut self, schema: &Schema) {
        macro_rules! keep {
            ($f:ident, $t:ty, $a:ident) => {
                if !schema.has(&Attribute::$a) {
                    self.$f = None;
                }
            };
        }
        for_each_column!(keep);
        if schema.extra_bytes == 0 {
            self.extra_bytes = None;
            self.extra_stride = 0;
        }
    }

    /// Gives the batch exactly the columns of `schema`: those it lacks filled with zeros, those
    /// `schema` does not name dropped (points decoded from files that disagree with their
    /// dataset's schema: an EPT node written in another LAS point format).
    pub fn conform(&mut self, schema: &Schema) {
        self.keep_columns(schema);
        let n = self.len();
        macro_rules! fill {
            ($f:ident, $t:ty, $a:ident) => {
                if schema.has(&Attribute::$a) && self.$f.is_none() {
                    self.$f = Some(vec![Default::default(); n]);
                }
            };
        }
        for_each_column!(fill);
        if schema.extra_bytes > 0 && self.extra_stride != schema.extra_bytes {
            let mut e = vec![0u8; n * schema.extra_bytes];
            if let Some(old) = &self.extra_bytes {
                let w = self.extra_stride.min(schema.extra_bytes);
                for i in 0..n {
                    let (from, to) = (i * self.extra_stride, i * schema.extra_bytes);
                    e[to..to + w].copy_from_slice(&old[from..from + w]);
                }
            }
            self.extra_bytes = Some(e);
            self.extra_stride = schema.extra_bytes;
        }
    }

    /// The schema of the columns this batch has.
    pub fn schema(&self) -> Schema {
        let mut attributes = Vec::new();
        macro_rules! has {
            ($f:ident, $t:ty, $a:ident) => {
                if self.$f.is_some() {
                    attributes.push(Attribute::$a);
                }
            };
        }
        for_each_column!(has);
        Schema {
            attributes,
            extra_bytes: if self.extra_bytes.is_some() {
                self.extra_stride
            } else {
                0
            },
        }
    }

    /// A copy of the points at `indices`, in that order.
    pub fn gather(&self, indices: &[u32]) -> PointBatch {
        let pick = |i: &u32| *i as usize;
        let mut b = PointBatch {
            positions: indices.iter().map(|i| self.positions[pick(i)]).collect(),
            ..Default::default()
        };
        macro_rules! g {
            ($f:ident, $t:ty, $a:ident) => {
                b.$f = self
                    .$f
                    .as_ref()
                    .map(|c| indices.iter().map(|i| c[pick(i)]).collect());
            };
        }
        for_each_column!(g);
        b.extra_stride = self.extra_stride;
        b.extra_bytes = self.extra_bytes.as_ref().map(|e| {
            let s = self.extra_stride;
            indices
                .iter()
                .flat_map(|i| e[pick(i) * s..(pick(i) + 1) * s].iter().copied())
                .collect()
        });
        b
    }

    /// A copy of the points in `range`.
    pub fn slice(&self, range: std::ops::Range<usize>) -> PointBatch {
        let mut b = PointBatch {
            positions: self.positions[range.clone()].to_vec(),
            ..Default::default()
        };
        macro_rules! sl {
            ($f:ident, $t:ty, $a:ident) => {
                b.$f = self.$f.as_ref().map(|c| c[range.clone()].to_vec());
            };
        }
        for_each_column!(sl);
        b.extra_stride = self.extra_stride;
        b.extra_bytes = self
            .extra_bytes
            .as_ref()
            .map(|e| e[range.start * self.extra_stride..range.end * self.extra_stride].to_vec());
        b
    }

    /// How many optional columns [`PointBatch::column_le`] numbers (every field but positions and
    /// extra bytes), in a fixed order: intensity, return_number, number_of_returns,
    /// classification, classification_flags, scan_flags, scanner_channel, scan_angle, user_data,
    /// point_source_id, gps_time, rgb, nir, wave_packet, normal.
    pub const COLUMNS: usize = 15;

    /// Optional column `k` (see [`PointBatch::COLUMNS`]) as little-endian element bytes, with
    /// its element size; `None` when the batch lacks it.
    pub fn column_le(&self, k: usize) -> Option<(usize, Vec<u8>)> {
        let mut i = 0;
        let mut out = None;
        macro_rules! get {
            ($f:ident, $t:ty, $a:ident) => {
                if i == k {
                    out = self.$f.as_ref().map(|c| {
                        let mut bytes = Vec::with_capacity(c.len() * <$t as RowBytes>::SIZE);
                        c.iter().for_each(|v| v.put(&mut bytes));
                        (<$t as RowBytes>::SIZE, bytes)
                    });
                }
                i += 1;
            };
        }
        for_each_column!(get);
        let _ = i;
        out
    }

    /// Column `k` as byte planes, with its value width: of each value's little-endian bytes
    /// ([`Self::column_le`]), all the first, then all the second, and so on (what a node page
    /// compresses), made without the bytes in between.
    pub fn column_planes(&self, k: usize) -> Option<(usize, Vec<u8>)> {
        fn planes<T: RowBytes>(c: &[T]) -> Vec<u8> {
            let (n, w) = (c.len(), T::SIZE);
            let mut out = vec![0u8; n * w];
            let mut value = [0u8; 64];
            for (i, v) in c.iter().enumerate() {
                v.write(&mut value);
                for (b, &byte) in value[..w].iter().enumerate() {
                    out[b * n + i] = byte;
                }
            }
            out
        }
        let mut i = 0;
        let mut out = None;
        macro_rules! get {
            ($f:ident, $t:ty, $a:ident) => {
                if i == k {
                    out = self
                        .$f
                        .as_ref()
                        .map(|c| (<$t as RowBytes>::SIZE, planes(c)));
                }
                i += 1;
            };
        }
        for_each_column!(get);
        let _ = i;
        out
    }

    /// Element size of optional column `k`.
    pub fn column_size(k: usize) -> usize {
        let mut i = 0;
        let mut size = 0;
        macro_rules! sz {
            ($f:ident, $t:ty, $a:ident) => {
                if i == k {
                    size = <$t as RowBytes>::SIZE;
                }
                i += 1;
            };
        }
        for_each_column!(sz);
        let _ = i;
        size
    }

    /// The attribute of optional column `k`.
    pub fn column_attribute(k: usize) -> Option<Attribute> {
        let mut i = 0;
        let mut attr = None;
        macro_rules! at {
            ($f:ident, $t:ty, $a:ident) => {
                if i == k {
                    attr = Some(Attribute::$a);
                }
                i += 1;
            };
        }
        for_each_column!(at);
        let _ = i;
        attr
    }

    /// Sets optional column `k` from little-endian element bytes (whole elements; a trailing
    /// partial element is ignored).
    pub fn set_column_le(&mut self, k: usize, bytes: &[u8]) {
        let mut i = 0;
        macro_rules! set {
            ($f:ident, $t:ty, $a:ident) => {
                if i == k {
                    self.$f = Some(
                        bytes
                            .chunks_exact(<$t as RowBytes>::SIZE)
                            .map(<$t as RowBytes>::get)
                            .collect(),
                    );
                }
                i += 1;
            };
        }
        for_each_column!(set);
        let _ = i;
    }

    /// Keeps the first `n` points.
    pub fn truncate(&mut self, n: usize) {
        self.positions.truncate(n);
        macro_rules! trunc {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &mut self.$f {
                    c.truncate(n);
                }
            };
        }
        for_each_column!(trunc);
        if let Some(e) = &mut self.extra_bytes {
            e.truncate(n * self.extra_stride);
        }
    }

    /// Keeps the points for which `keep[i]` is true, in order.
    pub fn retain_mask(&mut self, keep: &[bool]) {
        assert_eq!(keep.len(), self.len());
        fn filter<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut w = 0;
            for r in 0..v.len() {
                if keep[r] {
                    v[w] = v[r];
                    w += 1;
                }
            }
            v.truncate(w);
        }
        filter(&mut self.positions, keep);
        macro_rules! ret {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &mut self.$f {
                    filter(c, keep);
                }
            };
        }
        for_each_column!(ret);
        if let Some(e) = &mut self.extra_bytes {
            let s = self.extra_stride;
            let mut w = 0;
            for (i, &k) in keep.iter().enumerate() {
                if k {
                    e.copy_within(i * s..(i + 1) * s, w * s);
                    w += 1;
                }
            }
            e.truncate(w * s);
        }
    }

    /// Room for exactly `additional` more points in every column (`Vec::reserve_exact`).
    pub fn reserve_exact(&mut self, additional: usize) {
        self.positions.reserve_exact(additional);
        macro_rules! res {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &mut self.$f {
                    c.reserve_exact(additional);
                }
            };
        }
        for_each_column!(res);
        if let Some(e) = &mut self.extra_bytes {
            e.reserve_exact(additional * self.extra_stride);
        }
    }

    /// The points every column has room for.
    pub fn capacity(&self) -> usize {
        self.positions.capacity()
    }

    /// Appends the points `indices` of `other` (which has the same columns): `append` of a
    /// `gather`, without the batch between.
    pub fn extend_gather(&mut self, other: &PointBatch, indices: &[u32]) {
        let pick = |i: &u32| *i as usize;
        self.positions
            .extend(indices.iter().map(|i| other.positions[pick(i)]));
        macro_rules! ext {
            ($f:ident, $t:ty, $a:ident) => {
                match (&mut self.$f, &other.$f) {
                    (Some(a), Some(b)) => a.extend(indices.iter().map(|i| b[pick(i)])),
                    (None, None) => {}
                    _ => panic!("extend_gather: batches differ in column {}", stringify!($f)),
                }
            };
        }
        for_each_column!(ext);
        if let (Some(a), Some(b)) = (&mut self.extra_bytes, &other.extra_bytes) {
            let s = other.extra_stride;
            for i in indices {
                a.extend_from_slice(&b[pick(i) * s..(pick(i) + 1) * s]);
            }
        }
    }

    /// Appends `other`, which must carry the same columns.
    pub fn append(&mut self, other: &PointBatch) {
        self.positions.extend_from_slice(&other.positions);
        macro_rules! app {
            ($f:ident, $t:ty, $a:ident) => {
                match (&mut self.$f, &other.$f) {
                    (Some(a), Some(b)) => a.extend_from_slice(b),
                    (None, None) => {}
                    _ => panic!("append: batches differ in column {}", stringify!($f)),
                }
            };
        }
        for_each_column!(app);
        if let (Some(a), Some(b)) = (&mut self.extra_bytes, &other.extra_bytes) {
            a.extend_from_slice(b);
        }
    }

    /// Bytes of one row record of this batch's columns (see [`PointBatch::put_row`]).
    pub fn row_size(&self) -> usize {
        let mut n = <[f64; 3]>::SIZE + self.extra_stride * self.extra_bytes.is_some() as usize;
        macro_rules! size {
            ($f:ident, $t:ty, $a:ident) => {
                if self.$f.is_some() {
                    n += <$t>::SIZE;
                }
            };
        }
        for_each_column!(size);
        n
    }

    /// Appends point `i` as a row record: position, then each present column in the fixed
    /// column order, then the extra bytes. Read back with [`PointBatch::push_row`] on a batch
    /// with the same columns.
    pub fn put_row(&self, i: usize, out: &mut Vec<u8>) {
        self.positions[i].put(out);
        macro_rules! put {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &self.$f {
                    c[i].put(out);
                }
            };
        }
        for_each_column!(put);
        if let Some(e) = &self.extra_bytes {
            out.extend_from_slice(&e[i * self.extra_stride..(i + 1) * self.extra_stride]);
        }
    }

    /// Appends one row record written by [`PointBatch::put_row`] from a batch with these columns.
    pub fn push_row(&mut self, row: &[u8]) {
        let mut at = 0;
        self.positions.push(<[f64; 3]>::get(row));
        at += <[f64; 3]>::SIZE;
        macro_rules! get {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &mut self.$f {
                    c.push(<$t>::get(&row[at..]));
                    at += <$t>::SIZE;
                }
            };
        }
        for_each_column!(get);
        if let Some(e) = &mut self.extra_bytes {
            e.extend_from_slice(&row[at..at + self.extra_stride]);
        }
    }

    /// Checks that every column has one entry per point (a cheap invariant for tests and writers).
    pub fn is_consistent(&self) -> bool {
        let n = self.len();
        let mut ok = true;
        macro_rules! chk {
            ($f:ident, $t:ty, $a:ident) => {
                if let Some(c) = &self.$f {
                    ok &= c.len() == n;
                }
            };
        }
        for_each_column!(chk);
        if let Some(e) = &self.extra_bytes {
            ok &= e.len() == n * self.extra_stride;
        }
        ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> PointBatch {
        let mut s = Schema::new(vec![Attribute::Intensity, Attribute::Rgb]);
        s.extra_bytes = 2;
        let mut b = PointBatch::with_schema(&s, 4);
        for i in 0..4u16 {
            b.positions.push([i as f64, 0.0, 0.0]);
            b.intensity.as_mut().unwrap().push(i * 10);
            b.rgb.as_mut().unwrap().push([i, i, i]);
            b.extra_bytes
                .as_mut()
                .unwrap()
                .extend_from_slice(&[i as u8, 0xAA]);
        }
        b
    }

    #[test]
    fn retain_mask_keeps_rows_aligned() {
        let mut b = sample();
        b.retain_mask(&[true, false, false, true]);
        assert_eq!(b.len(), 2);
        assert_eq!(b.intensity.as_deref(), Some(&[0u16, 30][..]));
        assert_eq!(b.extra_bytes.as_deref(), Some(&[0u8, 0xAA, 3, 0xAA][..]));
        assert!(b.is_consistent());
        assert!(b.gps_time.is_none());
    }

    #[test]
    fn push_record_fills_every_column() {
        let s = Schema::new(vec![
            Attribute::Intensity,
            Attribute::Rgb,
            Attribute::Nir,
            Attribute::Normal,
        ]);
        let mut b = PointBatch::with_schema(&s, 1);
        b.push_record(&PointRecord {
            position: [1.0, 2.0, 3.0],
            intensity: 9,
            rgb: [1, 2, 3],
            ..Default::default()
        });
        assert!(b.is_consistent());
        assert_eq!(b.intensity, Some(vec![9]));
        assert_eq!(b.nir, Some(vec![0]));
        assert_eq!(b.normal, Some(vec![[0.0; 3]]));
        assert!(b.gps_time.is_none());
    }

    #[test]
    fn rows_round_trip() {
        let mut s = Schema::for_las_format(10);
        s.attributes.push(Attribute::Normal);
        s.extra_bytes = 3;
        let mut b = PointBatch::with_schema(&s, 2);
        for i in 0..2u8 {
            b.push_record(&PointRecord {
                position: [i as f64, 1.5, -2.25],
                intensity: 7,
                gps_time: 1e9 + i as f64,
                ..Default::default()
            });
        }
        b.wave_packet.as_mut().unwrap()[1] = WavePacket {
            descriptor_index: 3,
            byte_offset: 1 << 40,
            size: 9,
            return_point_location: 0.5,
            x_t: 1.0,
            y_t: 2.0,
            z_t: 3.0,
        };
        b.extra_bytes
            .as_mut()
            .unwrap()
            .copy_from_slice(&[1, 2, 3, 4, 5, 6]);
        let mut bytes = Vec::new();
        for i in 0..2 {
            b.put_row(i, &mut bytes);
        }
        assert_eq!(bytes.len(), 2 * b.row_size());
        let mut back = PointBatch::with_schema(&s, 2);
        for row in bytes.chunks_exact(b.row_size()) {
            back.push_row(row);
        }
        assert_eq!(back, b);
    }

    #[test]
    fn gather_and_schema() {
        let b = sample();
        let g = b.gather(&[3, 0]);
        assert_eq!(g.intensity, Some(vec![30, 0]));
        assert_eq!(g.extra_bytes, Some(vec![3, 0xAA, 0, 0xAA]));
        assert_eq!(g.schema(), b.schema());
        assert!(b.schema().has(&Attribute::Rgb) && !b.schema().has(&Attribute::GpsTime));
        assert_eq!(b.schema().extra_bytes, 2);
    }

    #[test]
    fn append_and_truncate() {
        let mut a = sample();
        a.append(&sample());
        assert_eq!(a.len(), 8);
        assert_eq!(
            a.slice(4..6).positions,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
        );
        assert_eq!(a.slice(4..6).extra_bytes.unwrap(), vec![0, 0xAA, 1, 0xAA]);
        a.truncate(5);
        assert_eq!(a.rgb.as_ref().unwrap().len(), 5);
        assert_eq!(a.extra_bytes.as_ref().unwrap().len(), 10);
        assert!(a.is_consistent());
    }
}
