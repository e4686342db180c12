//! SD card images for the virtual machine: an MBR with one FAT16 or FAT32
//! partition, formatted and filled with the `fatfs` crate.
//!
//! ```
//! use sim::sdimage::{FatKind, SdImage};
//! let img = SdImage::new(FatKind::Fat16).file("JOB.GCO", b"G1 X1 F600\n").build();
//! assert_eq!(&img[510..512], &[0x55, 0xAA]);
//! ```

use std::io::{Cursor, Write};

/// Which FAT the partition gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FatKind {
    Fat16,
    Fat32,
}

/// First block of the partition (after the MBR).
pub const PARTITION_START_BLOCK: u32 = 63;

/// Builder of a card image.
pub struct SdImage {
    kind: FatKind,
    files: Vec<(String, Vec<u8>)>,
    label: [u8; 11],
}

impl SdImage {
    /// An empty card of the given FAT kind.
    pub fn new(kind: FatKind) -> SdImage {
        SdImage { kind, files: Vec::new(), label: *b"MILL       " }
    }

    /// Add a file: a long or 8.3 name, in folders when the path has `/`
    /// (`JOBS/POCKET_ROUGH.GCODE`; the folders are made as needed).
    pub fn file(mut self, name: &str, contents: &[u8]) -> SdImage {
        self.files.push((name.to_string(), contents.to_vec()));
        self
    }

    /// Partition size in blocks: FAT32 needs at least 65 525 clusters, FAT16
    /// at least 4 085 (one block per cluster here).
    fn partition_blocks(&self) -> u32 {
        let data: u64 = self.files.iter().map(|(_, d)| d.len() as u64 + 1024).sum();
        let min = match self.kind {
            FatKind::Fat16 => 8 * 1024,  // 4 MiB
            FatKind::Fat32 => 72 * 1024, // 36 MiB
        };
        min.max((data / 512) as u32 * 2 + min)
    }

    /// Format, write the files and return the whole card image.
    pub fn build(&self) -> Vec<u8> {
        let blocks = self.partition_blocks();
        let mut part = vec![0u8; blocks as usize * 512];
        {
            let fat_type = match self.kind {
                FatKind::Fat16 => fatfs::FatType::Fat16,
                FatKind::Fat32 => fatfs::FatType::Fat32,
            };
            let opts = fatfs::FormatVolumeOptions::new().fat_type(fat_type).bytes_per_cluster(512).volume_label(self.label);
            fatfs::format_volume(Cursor::new(&mut part[..]), opts).expect("format FAT volume");
            let fs = fatfs::FileSystem::new(Cursor::new(&mut part[..]), fatfs::FsOptions::new()).expect("mount");
            for (path, data) in &self.files {
                let mut dir = fs.root_dir();
                let mut parts: Vec<&str> = path.split('/').collect();
                let name = parts.pop().expect("a file name");
                for p in parts {
                    dir = match dir.open_dir(p) {
                        Ok(d) => d,
                        Err(_) => dir.create_dir(p).expect("create folder"),
                    };
                }
                let mut f = dir.create_file(name).expect("create file");
                f.write_all(data).expect("write file");
            }
        }
        let mut img = vec![0u8; PARTITION_START_BLOCK as usize * 512];
        let e = 446;
        img[e] = 0x00; // not bootable
        img[e + 4] = match self.kind {
            FatKind::Fat16 => 0x0E, // FAT16 LBA
            FatKind::Fat32 => 0x0C, // FAT32 LBA
        };
        img[e + 8..e + 12].copy_from_slice(&PARTITION_START_BLOCK.to_le_bytes());
        img[e + 12..e + 16].copy_from_slice(&blocks.to_le_bytes());
        img[510] = 0x55;
        img[511] = 0xAA;
        img.extend_from_slice(&part);
        img
    }
}

/// Where a file's data and its FAT chain sit in an image, for tests that
/// corrupt it.
#[derive(Clone, Debug)]
pub struct FileLayout {
    /// Absolute byte offsets of the file's clusters, in order.
    pub cluster_offsets: Vec<usize>,
    /// Absolute byte offset of each cluster's FAT entry (same order).
    pub fat_entry_offsets: Vec<usize>,
    /// Bytes per FAT entry (2 or 4).
    pub fat_entry_len: usize,
}

/// Find a root-directory file in an image built by [`SdImage`] and return
/// where its clusters and FAT entries are.
pub fn locate(img: &[u8], name: &str) -> Option<FileLayout> {
    let p = PARTITION_START_BLOCK as usize * 512;
    let rd16 = |o: usize| u16::from_le_bytes([img[o], img[o + 1]]) as usize;
    let rd32 = |o: usize| u32::from_le_bytes([img[o], img[o + 1], img[o + 2], img[o + 3]]) as usize;
    let bps = rd16(p + 11);
    let spc = img[p + 13] as usize;
    let reserved = rd16(p + 14);
    let nfats = img[p + 16] as usize;
    let root_entries = rd16(p + 17);
    let fat16_size = rd16(p + 22);
    let fat32 = fat16_size == 0;
    let fat_size = if fat32 { rd32(p + 36) } else { fat16_size };
    let fat_start = p + reserved * bps;
    let root_dir_blocks = (root_entries * 32).div_ceil(bps);
    let data_start = fat_start + nfats * fat_size * bps + root_dir_blocks * bps;
    let cluster_bytes = spc * bps;
    let cluster_off = |c: usize| data_start + (c - 2) * cluster_bytes;
    let entry_len = if fat32 { 4 } else { 2 };
    let next = |c: usize| {
        if fat32 {
            rd32(fat_start + c * 4) & 0x0FFF_FFFF
        } else {
            rd16(fat_start + c * 2)
        }
    };
    // 8.3 name as stored.
    let (base, ext) = name.split_once('.').unwrap_or((name, ""));
    let mut short = [b' '; 11];
    for (i, b) in base.bytes().take(8).enumerate() {
        short[i] = b.to_ascii_uppercase();
    }
    for (i, b) in ext.bytes().take(3).enumerate() {
        short[8 + i] = b.to_ascii_uppercase();
    }
    // Root directory: fixed area (FAT16) or a cluster chain (FAT32).
    let mut dir_areas: Vec<(usize, usize)> = Vec::new();
    if fat32 {
        let mut c = rd32(p + 44);
        while (2..0x0FFF_FFF8).contains(&c) {
            dir_areas.push((cluster_off(c), cluster_bytes));
            c = next(c);
        }
    } else {
        dir_areas.push((fat_start + nfats * fat_size * bps, root_entries * 32));
    }
    for (start, len) in dir_areas {
        for e in (start..start + len).step_by(32) {
            if img[e] == 0 {
                return None;
            }
            if img[e..e + 11] == short && img[e + 11] & 0x08 == 0 {
                let mut c = rd16(e + 26) | if fat32 { rd16(e + 20) << 16 } else { 0 };
                let mut layout = FileLayout { cluster_offsets: vec![], fat_entry_offsets: vec![], fat_entry_len: entry_len };
                let end = if fat32 { 0x0FFF_FFF8 } else { 0xFFF8 };
                while c >= 2 && c < end {
                    layout.cluster_offsets.push(cluster_off(c));
                    layout.fat_entry_offsets.push(fat_start + c * entry_len);
                    c = next(c);
                }
                return Some(layout);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    fn read_back(img: &[u8], name: &str) -> Vec<u8> {
        let p = PARTITION_START_BLOCK as usize * 512;
        let mut part = img[p..].to_vec();
        let fs = fatfs::FileSystem::new(Cursor::new(&mut part[..]), fatfs::FsOptions::new()).unwrap();
        let mut f = fs.root_dir().open_file(name).unwrap();
        let mut v = Vec::new();
        f.read_to_end(&mut v).unwrap();
        v
    }

    #[test]
    fn fat16_and_fat32_images_hold_their_files() {
        let data: Vec<u8> = (0..3000u32).map(|i| (i % 251) as u8).collect();
        for kind in [FatKind::Fat16, FatKind::Fat32] {
            let img = SdImage::new(kind).file("A.GCO", b"G0 X1\n").file("BIG.NC", &data).build();
            assert_eq!(read_back(&img, "BIG.NC"), data);
            let l = locate(&img, "BIG.NC").unwrap();
            assert_eq!(l.cluster_offsets.len(), 6, "{kind:?}");
            assert_eq!(&img[l.cluster_offsets[1]..l.cluster_offsets[1] + 4], &data[512..516]);
            assert_eq!(l.fat_entry_len, if kind == FatKind::Fat32 { 4 } else { 2 });
        }
    }
}
