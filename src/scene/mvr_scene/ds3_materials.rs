//! The material chunks of a 3DS file (issue 14 item 4): each material's
//! name, diffuse colour and diffuse texture-map file name, read for the MVR
//! importer (`mvr_scene`), which turns them into Lambert materials with an
//! optional base-colour texture.
//!
//! Hand-written because the `ds3` crate (0.1.0), which reads the meshes,
//! exposes only the material *names* (`Scene3ds::materials`,
//! `Mesh3ds::material`), not the material chunks (ds3 stays the mesh
//! reader, chosen after checking crates.io: docs/mvr-gdtf.md). The chunks
//! read (3D Studio file format, as lib3ds and Assimp read it):
//!
//! ```text
//! MAIN 0x4D4D → EDIT3DS 0x3D3D → MAT_ENTRY 0xAFFF → MAT_NAME 0xA000 (C string)
//!                                               → MAT_DIFFUSE 0xA020 → COLOR_F 0x0010 (3 × f32)
//!                                                                    → COLOR_24 0x0011 (3 × u8)
//!                                                                    → LIN_COLOR_24 0x0012 (3 × u8)
//!                                                                    → LIN_COLOR_F 0x0013 (3 × f32)
//!                                               → MAT_TEXMAP 0xA200 → MAT_MAPNAME 0xA300 (C string)
//! ```
//!
//! Colours: the `LIN_` variants are linear and preferred when present (float
//! before byte); `COLOR_24` and `COLOR_F` are gamma-corrected and read as
//! sRGB-encoded (IEC 61966-2-1) → linear. Values are clamped to 0..1 (an
//! albedo); a non-finite float colour counts as absent.
//!
//! Which faces use which material: `MSH_MAT_GROUP` 0x4130 (material name,
//! face count, face indices), which real files nest in `FACE_ARRAY` 0x4120
//! (inside `NAMED_OBJECT` 0x4000 → `N_TRI_OBJECT` 0x4100). `ds3` 0.1 looks
//! for it only directly in 0x4100 (where it writes it), so it misses the
//! material of a real file's meshes; both places are read here, one entry
//! per named object with a triangle mesh, in file order (the order of
//! `ds3`'s meshes).
//!
//! Every read is bounds-checked: a chunk whose length runs past its parent,
//! a truncated header or a C string without its NUL is an error naming the
//! chunk and its offset; nothing panics on any input. The number of
//! materials is capped ([`MAX_MATERIALS`]), like the importer's triangle
//! budget.

use crate::scene::texture::srgb_to_linear;

/// Most materials read from one file (a real venue model has tens; more is
/// a damaged or hostile file, refused with an error).
pub const MAX_MATERIALS: usize = 65_536;

/// Longest C string read (material and map names), bytes.
const MAX_NAME: usize = 1024;

/// One 3DS material as the importer needs it.
#[derive(Clone, Debug, PartialEq)]
pub struct Material3ds {
    /// `MAT_NAME` (lossy UTF-8); the key meshes name in `MSH_MAT_GROUP`.
    pub name: String,
    /// Diffuse colour, linear RGB in 0..1; `None` when the material has no
    /// readable `MAT_DIFFUSE` colour.
    pub diffuse: Option<[f32; 3]>,
    /// `MAT_TEXMAP` → `MAT_MAPNAME`: the diffuse texture's file name as
    /// written (often an 8.3 DOS name).
    pub texture_map: Option<String>,
}

/// One `MSH_MAT_GROUP`: the faces of a mesh in one material.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceGroup {
    /// The material's name (`MAT_NAME`).
    pub material: String,
    /// Indices into the mesh's faces (unchecked: the importer ignores an
    /// index past the faces).
    pub faces: Vec<u16>,
}

/// What this reader takes from a 3DS file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialChunks {
    /// The materials, in file order.
    pub materials: Vec<Material3ds>,
    /// Per triangle mesh (named object with an `N_TRI_OBJECT`, in file
    /// order, as `ds3` lists them): its face groups.
    pub face_groups: Vec<Vec<FaceGroup>>,
}

#[derive(Clone, Copy)]
struct Chunk {
    id: u16,
    offset: usize,
    data: usize,
    end: usize,
}

/// The chunks directly inside `bytes[start..end]`, each bounds-checked.
fn children(bytes: &[u8], start: usize, end: usize) -> Result<Vec<Chunk>, String> {
    let mut out = Vec::new();
    let mut at = start;
    while at < end {
        let c = chunk_at(bytes, at, end)?;
        out.push(c);
        at = c.end;
    }
    Ok(out)
}

/// The chunk starting at byte `at` of a parent ending at byte `end`.
fn chunk_at(bytes: &[u8], at: usize, end: usize) -> Result<Chunk, String> {
    let end = end.min(bytes.len());
    let header = bytes
        .get(at..at.saturating_add(6))
        .filter(|_| at.saturating_add(6) <= end)
        .ok_or_else(|| format!("a truncated chunk header at byte {at} (its parent ends at byte {end})"))?;
    let id = u16::from_le_bytes([header[0], header[1]]);
    let len = u32::from_le_bytes([header[2], header[3], header[4], header[5]]) as usize;
    let chunk_end = at.checked_add(len).filter(|&e| len >= 6 && e <= end).ok_or_else(|| {
        format!("chunk 0x{id:04X} at byte {at}: its length {len} runs past its parent (ends at byte {end})")
    })?;
    Ok(Chunk { id, offset: at, data: at + 6, end: chunk_end })
}

/// The C string opening chunk `c`'s data (lossy UTF-8), and the bytes it
/// takes with its NUL.
fn cstring_len(bytes: &[u8], c: Chunk) -> Result<(String, usize), String> {
    let data = &bytes[c.data..c.end];
    let n = data
        .iter()
        .take(MAX_NAME)
        .position(|&b| b == 0)
        .ok_or_else(|| format!("chunk 0x{:04X} at byte {}: a name without its NUL", c.id, c.offset))?;
    Ok((String::from_utf8_lossy(&data[..n]).into_owned(), n + 1))
}

fn cstring(bytes: &[u8], c: Chunk) -> Result<String, String> {
    cstring_len(bytes, c).map(|(s, _)| s)
}

/// A colour sub-chunk's value, linear; `None` when too short or non-finite.
fn colour(bytes: &[u8], c: Chunk) -> Option<[f32; 3]> {
    let d = &bytes[c.data..c.end];
    let rgb = match c.id {
        0x0010 | 0x0013 => {
            let f = |i: usize| d.get(4 * i..4 * i + 4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
            let v = [f(0)?, f(1)?, f(2)?];
            if !v.iter().all(|x| x.is_finite()) {
                return None;
            }
            v.map(|x| x.clamp(0.0, 1.0))
        }
        0x0011 | 0x0012 => {
            let b = d.get(0..3)?;
            [b[0], b[1], b[2]].map(|x| f32::from(x) / 255.0)
        }
        _ => return None,
    };
    Some(if c.id == 0x0010 || c.id == 0x0011 { rgb.map(srgb_to_linear) } else { rgb })
}

fn material(bytes: &[u8], entry: Chunk) -> Result<Material3ds, String> {
    let mut m = Material3ds { name: String::new(), diffuse: None, texture_map: None };
    for c in children(bytes, entry.data, entry.end)? {
        match c.id {
            0xA000 => m.name = cstring(bytes, c)?,
            0xA020 => {
                // Linear float, linear byte, gamma float, gamma byte: first found wins.
                let subs = children(bytes, c.data, c.end)?;
                m.diffuse = [0x0013, 0x0012, 0x0010, 0x0011]
                    .iter()
                    .find_map(|&id| subs.iter().filter(|s| s.id == id).find_map(|&s| colour(bytes, s)));
            }
            0xA200 => {
                for s in children(bytes, c.data, c.end)? {
                    if s.id == 0xA300 {
                        m.texture_map = Some(cstring(bytes, s)?).filter(|n| !n.is_empty());
                    }
                }
            }
            _ => {}
        }
    }
    Ok(m)
}

/// A `MSH_MAT_GROUP` chunk's material name and face indices.
fn face_group(bytes: &[u8], c: Chunk) -> Result<FaceGroup, String> {
    let (material, len) = cstring_len(bytes, c)?;
    let at = c.data + len;
    let d = &bytes[at.min(c.end)..c.end];
    let count = d.get(0..2).map(|b| usize::from(u16::from_le_bytes([b[0], b[1]])));
    let faces = count
        .and_then(|n| d.get(2..2 + 2 * n))
        .ok_or_else(|| format!("MSH_MAT_GROUP 0x4130 at byte {}: its face list is truncated", c.offset))?
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    Ok(FaceGroup { material, faces })
}

/// The face groups of one `N_TRI_OBJECT`: inside its `FACE_ARRAY` (after
/// the face count and the faces, 8 bytes each) and directly in it.
fn mesh_groups(bytes: &[u8], trimesh: Chunk) -> Result<Vec<FaceGroup>, String> {
    let mut out = Vec::new();
    for c in children(bytes, trimesh.data, trimesh.end)? {
        match c.id {
            0x4130 => out.push(face_group(bytes, c)?),
            0x4120 => {
                let n = bytes
                    .get(c.data..c.data + 2)
                    .filter(|_| c.data + 2 <= c.end)
                    .map(|b| usize::from(u16::from_le_bytes([b[0], b[1]])))
                    .ok_or_else(|| format!("FACE_ARRAY 0x4120 at byte {}: truncated", c.offset))?;
                let subs = c.data + 2 + 8 * n;
                if subs > c.end {
                    return Err(format!("FACE_ARRAY 0x4120 at byte {}: {n} faces run past its end", c.offset));
                }
                for s in children(bytes, subs, c.end)? {
                    if s.id == 0x4130 {
                        out.push(face_group(bytes, s)?);
                    }
                }
            }
            _ => {}
        }
    }
    Ok(out)
}

/// The materials and face groups of the 3DS file `bytes`. A file that is
/// not a 3DS (no `MAIN` chunk first) or whose chunks run past their parents
/// is an error saying where; a file without an editor chunk has none.
pub fn read_materials(bytes: &[u8]) -> Result<MaterialChunks, String> {
    // Only the first chunk: bytes after MAIN (padding some exporters add) are not read.
    let main = chunk_at(bytes, 0, bytes.len())?;
    if main.id != 0x4D4D {
        return Err("not a 3DS file (no MAIN chunk 0x4D4D first)".to_string());
    }
    let mut out = MaterialChunks::default();
    for edit in children(bytes, main.data, main.end)?.into_iter().filter(|c| c.id == 0x3D3D) {
        for entry in children(bytes, edit.data, edit.end)? {
            match entry.id {
                0xAFFF => {
                    if out.materials.len() >= MAX_MATERIALS {
                        return Err(format!("more than {MAX_MATERIALS} materials"));
                    }
                    out.materials.push(material(bytes, entry)?);
                }
                0x4000 => {
                    let (_, len) = cstring_len(bytes, entry)?;
                    let start = entry.data + len;
                    // The first triangle mesh, as ds3 takes it.
                    if let Some(t) = children(bytes, start, entry.end)?.into_iter().find(|c| c.id == 0x4100) {
                        out.face_groups.push(mesh_groups(bytes, t)?);
                    }
                }
                _ => {}
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(id: u16, payload: &[u8]) -> Vec<u8> {
        let mut v = id.to_le_bytes().to_vec();
        v.extend(((6 + payload.len()) as u32).to_le_bytes());
        v.extend(payload);
        v
    }

    fn file(entries: &[Vec<u8>]) -> Vec<u8> {
        let mats: Vec<u8> = entries.iter().flat_map(|e| chunk(0xAFFF, e)).collect();
        chunk(0x4D4D, &[chunk(0x0002, &3u32.to_le_bytes()), chunk(0x3D3D, &mats)].concat())
    }

    fn srgb(b: u8) -> f32 {
        let c = f64::from(b) / 255.0;
        (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
    }

    fn sample() -> Vec<u8> {
        let red = [chunk(0xA000, b"Red\0"), chunk(0xA020, &chunk(0x0011, &[200, 40, 10]))].concat();
        let floats: Vec<u8> = [0.25f32, 0.5, 0.75].iter().flat_map(|f| f.to_le_bytes()).collect();
        let both = [
            chunk(0xA000, b"Both\0"),
            chunk(0xA020, &[chunk(0x0011, &[255, 255, 255]), chunk(0x0013, &floats)].concat()),
            chunk(0xA200, &[chunk(0x0030, &[0x64, 0]), chunk(0xA300, b"WOOD.PNG\0")].concat()),
        ]
        .concat();
        file(&[red, both, chunk(0xA000, b"Bare\0")])
    }

    #[test]
    fn names_colours_and_maps_are_read() {
        let m = read_materials(&sample()).unwrap().materials;
        assert_eq!(m.len(), 3);
        assert_eq!(m[0].name, "Red");
        let want = [srgb(200), srgb(40), srgb(10)];
        for (g, w) in m[0].diffuse.unwrap().iter().zip(want) {
            assert!((g - w).abs() < 1e-6, "{g} vs {w}");
        }
        assert_eq!(m[0].texture_map, None);
        // The linear float colour wins over the gamma-corrected byte colour.
        assert_eq!(m[1].diffuse, Some([0.25, 0.5, 0.75]));
        assert_eq!(m[1].texture_map.as_deref(), Some("WOOD.PNG"));
        assert_eq!(m[2], Material3ds { name: "Bare".into(), diffuse: None, texture_map: None });
    }

    #[test]
    fn face_groups_are_read_inside_and_beside_the_face_array() {
        let group = |name: &[u8], faces: &[u16]| {
            let mut d = name.to_vec();
            d.push(0);
            d.extend((faces.len() as u16).to_le_bytes());
            d.extend(faces.iter().flat_map(|f| f.to_le_bytes()));
            chunk(0x4130, &d)
        };
        let mut face_array = 2u16.to_le_bytes().to_vec();
        face_array.extend([0u8; 16]);
        face_array.extend(group(b"Red", &[1]));
        face_array.extend(group(b"Blue", &[0]));
        // Real files: groups inside FACE_ARRAY; ds3's writer: in N_TRI_OBJECT.
        let real = chunk(0x4000, &[b"a\0".to_vec(), chunk(0x4100, &chunk(0x4120, &face_array))].concat());
        let ds3_style = chunk(0x4000, &[b"b\0".to_vec(), chunk(0x4100, &group(b"Red", &[]))].concat());
        let light = chunk(0x4000, &[b"lamp\0".to_vec(), chunk(0x4600, &[0; 12])].concat());
        let bytes = chunk(0x4D4D, &chunk(0x3D3D, &[real, light, ds3_style].concat()));
        let g = read_materials(&bytes).unwrap().face_groups;
        let fg = |m: &str, f: &[u16]| FaceGroup { material: m.into(), faces: f.to_vec() };
        assert_eq!(g, vec![vec![fg("Red", &[1]), fg("Blue", &[0])], vec![fg("Red", &[])]]);
        // A face count past the chunk is an error.
        face_array[0] = 200;
        let bad = chunk(
            0x4D4D,
            &chunk(0x3D3D, &chunk(0x4000, &[b"a\0".to_vec(), chunk(0x4100, &chunk(0x4120, &face_array))].concat())),
        );
        assert!(read_materials(&bad).unwrap_err().contains("0x4120"));
    }

    #[test]
    fn broken_chunks_are_errors_not_panics() {
        let good = sample();
        // A length past the end, a truncated file, a name without its NUL.
        let mut long = good.clone();
        long[2..6].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(read_materials(&long).unwrap_err().contains("0x4D4D"));
        assert!(read_materials(&good[..good.len() - 3]).is_err());
        let no_nul = file(&[chunk(0xA000, b"Red")]);
        assert!(read_materials(&no_nul).unwrap_err().contains("NUL"));
        assert!(read_materials(&[]).is_err());
        assert!(read_materials(b"PK\x03\x04 not a 3ds").is_err());
        // Seeded mutations and truncations of a good file, and random bytes:
        // an answer or an error, never a panic.
        let mut state = 0x3D5_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let (mut ok, mut err) = (0, 0);
        for i in 0..20_000 {
            let mut bytes = if i % 4 == 0 {
                (0..next() % 200).map(|_| next() as u8).collect()
            } else {
                let mut b = good.clone();
                for _ in 0..1 + next() % 4 {
                    let at = next() as usize % b.len();
                    b[at] = next() as u8;
                }
                b
            };
            if i % 5 == 1 {
                bytes.truncate(next() as usize % (bytes.len() + 1));
            }
            match read_materials(&bytes) {
                Ok(m) => {
                    ok += 1;
                    assert!(m.materials.iter().flat_map(|m| m.diffuse).flatten().all(|c| (0.0..=1.0).contains(&c)));
                }
                Err(_) => err += 1,
            }
        }
        assert!(ok > 1000 && err > 1000, "ok {ok}, err {err}");
    }
}
