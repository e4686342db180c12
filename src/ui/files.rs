//! The Files screen's list: the current folder's folders first, then its
//! files, each group sorted by name (the long name where the card has one,
//! ignoring case), read from the card a screenful at a time.
//!
//! Nothing is sorted in RAM beyond the 7 rows on screen. One pass over the
//! folder fills the free rows with the smallest entries after the last row
//! (or, scrolling up, the largest before the first row), so a scroll by one
//! row costs one pass, like the plain directory listing it replaces; a jump
//! of n rows costs n / 7 + 1 passes. RAM: the rows' text (7 × 18 bytes),
//! their directory positions (7 bytes) and 5 bytes of state.
//!
//! The order compares the first [`KEY_CHARS`] characters of the names, then
//! the directory position, which is unique, so every entry is listed once.
//! A folder lists its first 255 entries.

use super::sd::{Card, Entry, Folder, Name, SdError};

/// File rows on the Files screen (below the title).
pub const ROWS: usize = 7;
/// Characters of a row's name kept for the display.
pub const ROW_CHARS: usize = 18;
/// Characters of a name the order looks at: all but the last of a row,
/// which is `~` when the name is cut.
pub const KEY_CHARS: usize = ROW_CHARS - 1;

/// The order of an entry: folders first, then the name without case, then
/// the position in the directory.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
struct Key {
    file: bool,
    text: [u8; KEY_CHARS],
    pos: u8,
}

impl Key {
    fn new(dir: bool, text: &[u8; ROW_CHARS], pos: u8) -> Key {
        let mut k = Key { file: !dir, text: [0; KEY_CHARS], pos };
        for (d, &c) in k.text.iter_mut().zip(text) {
            *d = c.to_ascii_lowercase();
        }
        k
    }
}

/// One row's text: the name (long, else 8.3) cut to [`ROW_CHARS`]
/// characters, the last one `~` when cut, zero-padded; bytes the font
/// cannot draw show as `?`.
fn row_text(e: &Entry<'_>) -> [u8; ROW_CHARS] {
    let name = if e.long.is_empty() { e.name.as_bytes() } else { e.long.as_bytes() };
    let mut t = [0u8; ROW_CHARS];
    for (d, &c) in t.iter_mut().zip(name) {
        *d = if (0x20..0x7F).contains(&c) { c } else { b'?' };
    }
    if name.len() > ROW_CHARS {
        t[ROW_CHARS - 1] = b'~';
    }
    t
}

/// The visible rows of the Files screen, and the folder's entry count.
pub struct FileList {
    rows: [[u8; ROW_CHARS]; ROWS],
    /// Directory position of each row's entry.
    pos: [u8; ROWS],
    /// Bit r: row r is a folder.
    dirs: u8,
    /// Rows holding an entry (from row 0).
    filled: u8,
    /// Sorted index of row 0.
    pub first: u8,
    /// Entries in the folder (after the last refresh; at most 255).
    pub count: u8,
    /// The rows are those of `first` in the current folder.
    pub valid: bool,
}

impl Default for FileList {
    fn default() -> Self {
        FileList::new()
    }
}

impl FileList {
    pub const fn new() -> FileList {
        FileList { rows: [[0; ROW_CHARS]; ROWS], pos: [0; ROWS], dirs: 0, filled: 0, first: 0, count: 0, valid: false }
    }

    fn key(&self, r: usize) -> Key {
        Key::new(self.dirs & (1 << r) != 0, &self.rows[r], self.pos[r])
    }

    /// Row r's key against `k`, lowercasing as it goes (most names differ
    /// in their first characters).
    fn cmp_row(&self, r: usize, k: &Key) -> core::cmp::Ordering {
        let file = self.dirs & (1 << r) == 0;
        file.cmp(&k.file)
            .then_with(|| {
                let row = self.rows[r].iter().map(u8::to_ascii_lowercase);
                row.take(KEY_CHARS).cmp(k.text.iter().copied())
            })
            .then(self.pos[r].cmp(&k.pos))
    }

    fn put(&mut self, r: usize, text: &[u8; ROW_CHARS], pos: u8, dir: bool) {
        self.rows[r] = *text;
        self.pos[r] = pos;
        self.dirs = (self.dirs & !(1 << r)) | ((dir as u8) << r);
    }

    fn copy(&mut self, from: usize, to: usize) {
        let (t, p, d) = (self.rows[from], self.pos[from], self.dirs & (1 << from) != 0);
        self.put(to, &t, p, d);
    }

    /// One pass over the folder: count its entries, and put into rows
    /// `lo_row..hi_row` (empty) the entries between the keys `after` and
    /// `before`, in order: the smallest ones, or with `largest` the largest.
    fn fill(
        &mut self,
        card: &mut impl Card,
        rows: (usize, usize),
        after: Option<Key>,
        before: Option<Key>,
        largest: bool,
    ) -> Result<(), SdError> {
        let (lo, hi) = rows;
        let mut n = 0; // rows lo..lo + n hold entries, in order
        let mut pos: u16 = 0;
        card.list(Folder::Current, &mut |e| {
            let Ok(p) = u8::try_from(pos) else {
                return;
            };
            pos += 1;
            let text = row_text(e);
            let k = Key::new(e.dir, &text, p);
            if after.is_some_and(|a| k <= a) || before.is_some_and(|b| k >= b) {
                return;
            }
            // Rows lo..lo + at hold smaller keys.
            let at = (lo..lo + n).take_while(|&r| self.cmp_row(r, &k).is_lt()).count();
            if lo + n < hi {
                for r in (lo + at..lo + n).rev() {
                    self.copy(r, r + 1);
                }
                self.put(lo + at, &text, p, e.dir);
                n += 1;
            } else if largest && at > 0 {
                // Full: drop the smallest.
                for r in lo + 1..lo + at {
                    self.copy(r, r - 1);
                }
                self.put(lo + at - 1, &text, p, e.dir);
            } else if !largest && lo + at < hi {
                // Full: drop the largest.
                for r in (lo + at..hi - 1).rev() {
                    self.copy(r, r + 1);
                }
                self.put(lo + at, &text, p, e.dir);
            }
        })?;
        self.count = pos.min(255) as u8;
        if largest && lo + n < hi {
            // Fewer than asked for: close the gap up to row hi.
            let gap = hi - lo - n;
            for r in (lo..lo + n).rev() {
                self.copy(r, r + gap);
            }
        }
        Ok(())
    }

    /// Move the rows `d` entries down the list (toward its end).
    fn forward(&mut self, card: &mut impl Card, d: usize) -> Result<(), SdError> {
        let filled = self.filled as usize;
        let last = filled.checked_sub(1).map(|r| self.key(r));
        let keep = filled.saturating_sub(d);
        for r in 0..keep {
            self.copy(r + d, r);
        }
        self.fill(card, (keep, ROWS), last, None, false)?;
        self.first = self.first.saturating_add(d as u8);
        self.filled = (self.count.saturating_sub(self.first) as usize).min(ROWS) as u8;
        Ok(())
    }

    /// Move the rows `d` entries up the list (toward its start; d < ROWS).
    fn back(&mut self, card: &mut impl Card, d: usize) -> Result<(), SdError> {
        let top = self.key(0);
        for r in (0..ROWS - d).rev() {
            self.copy(r, r + d);
        }
        self.fill(card, (0, d), None, Some(top), true)?;
        self.first -= d as u8;
        self.filled = (self.count.saturating_sub(self.first) as usize).min(ROWS) as u8;
        Ok(())
    }

    /// Show the rows from sorted entry `first` on, and count the folder's
    /// entries (a missing or unreadable card lists nothing).
    pub fn refresh(&mut self, card: &mut impl Card, first: u8) {
        let r = card.mount().and_then(|_| {
            if self.valid && first < self.first && self.first - first < ROWS as u8 && self.filled > 0 {
                return self.back(card, (self.first - first) as usize);
            }
            if !self.valid || first < self.first {
                self.first = 0;
                self.filled = 0;
                self.forward(card, 0)?;
            }
            while self.first < first && self.filled > 0 {
                self.forward(card, ((first - self.first) as usize).min(ROWS))?;
            }
            Ok(())
        });
        if r.is_err() {
            self.count = 0;
            self.filled = 0;
        }
        self.valid = true;
    }

    /// Bit r: row r is a folder (none while the rows are stale).
    pub fn dirs(&self) -> u8 {
        if self.valid {
            self.dirs
        } else {
            0
        }
    }

    /// Row text and kind of sorted entry `i`, when it is on screen.
    pub fn row(&self, i: u8) -> Option<(&[u8], bool)> {
        let r = i.checked_sub(self.first)? as usize;
        if !self.valid || r >= self.filled as usize {
            return None;
        }
        let t = &self.rows[r];
        let len = t.iter().position(|&c| c == 0).unwrap_or(ROW_CHARS);
        Some((&t[..len], self.dirs & (1 << r) != 0))
    }

    /// Rows as a test wants them: entry i is the file `name(i)`, `count` of them.
    #[cfg(test)]
    pub fn for_test(first: u8, count: u8, name: impl Fn(u8) -> String) -> FileList {
        let filled = count.saturating_sub(first).min(ROWS as u8);
        let mut l = FileList { first, count, filled, valid: true, ..FileList::new() };
        for (r, row) in l.rows.iter_mut().enumerate() {
            let n = name(first + r as u8);
            row[..n.len()].copy_from_slice(n.as_bytes());
        }
        l
    }

    /// The 8.3 name and kind of sorted entry `i`, when it is on screen.
    pub fn entry(&self, card: &mut impl Card, i: u8) -> Option<(Name, bool)> {
        self.row(i)?;
        let want = self.pos[(i - self.first) as usize];
        let mut pos: u16 = 0;
        let mut found = None;
        card.list(Folder::Current, &mut |e| {
            if pos == want as u16 {
                found = Some((e.name, e.dir));
            }
            pos += 1;
        })
        .ok()?;
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ui::sd::tests::FakeCard;

    fn card() -> FakeCard {
        let mut c = FakeCard::new(&[]);
        c.add("", "ZED.NC", "", false, "G0 X1\n")
            .add("", "POCKET~1.GCO", "POCKET_ROUGH.GCODE", false, "G0 X2\n")
            .add("", "JOBS", "", true, "")
            .add("", "ALPHA.NC", "alpha.nc", false, "G0 X3\n")
            .add("", "ARCHIVE", "Archive", true, "")
            .add("JOBS", "FACE.NC", "face mill.nc", false, "G0 X4\n")
            .add("JOBS", "BRACKE~1.NC", "bracket_v2_final_final.nc", false, "G0 X5\n");
        c
    }

    fn rows(l: &FileList) -> Vec<(String, bool)> {
        (0..l.count).filter_map(|i| l.row(i)).map(|(t, d)| (String::from_utf8(t.to_vec()).unwrap(), d)).collect()
    }

    #[test]
    fn folders_come_first_then_files_each_by_name_ignoring_case() {
        let mut c = card();
        let mut l = FileList::new();
        l.refresh(&mut c, 0);
        assert_eq!(l.count, 5);
        let names: Vec<_> = rows(&l);
        assert_eq!(
            names,
            [("Archive", true), ("JOBS", true), ("alpha.nc", false), ("POCKET_ROUGH.GCODE", false), ("ZED.NC", false)]
                .map(|(n, d)| (n.to_string(), d))
        );
        assert_eq!(l.entry(&mut c, 3), Some((Name::parse(b"POCKET~1.GCO").unwrap(), false)));
        assert_eq!(l.entry(&mut c, 1), Some((Name::parse(b"JOBS").unwrap(), true)));
        assert_eq!(l.entry(&mut c, 5), None);
    }

    #[test]
    fn a_screen_from_an_entry_on_lists_the_sorted_tail() {
        let mut c = card();
        let mut l = FileList::new();
        l.refresh(&mut c, 3);
        assert_eq!(l.row(2), None);
        assert_eq!(l.row(3).unwrap().0, b"POCKET_ROUGH.GCODE");
        assert_eq!(l.row(4).unwrap().0, b"ZED.NC");
        assert_eq!(l.row(5), None);
    }

    #[test]
    fn a_folder_lists_its_own_entries_and_leaving_it_lists_the_root_again() {
        let mut c = card();
        let mut l = FileList::new();
        c.enter(&Name::parse(b"JOBS").unwrap()).unwrap();
        l.valid = false; // as the firmware does on a change of folder
        l.refresh(&mut c, 0);
        // A name past 18 characters ends in `~`.
        assert_eq!(rows(&l), [("bracket_v2_final_~".to_string(), false), ("face mill.nc".to_string(), false)]);
        c.leave().unwrap();
        l.valid = false;
        l.refresh(&mut c, 0);
        assert_eq!(l.count, 5);
    }

    #[test]
    fn names_alike_in_their_first_characters_are_ordered_by_their_place_on_the_card_and_each_listed_once() {
        let mut c = FakeCard::new(&[]);
        let long = "a".repeat(30);
        for n in ["B.NC", "A.NC", "C.NC"] {
            c.add("", n, &long, false, "");
        }
        let mut l = FileList::new();
        l.refresh(&mut c, 0);
        let all: Vec<_> = (0..4).map(|i| l.entry(&mut c, i).map(|(n, _)| n.as_str().to_string())).collect();
        assert_eq!(all, [Some("B.NC".into()), Some("A.NC".into()), Some("C.NC".into()), None]);
    }

    /// A folder of `n` files named by a scrambled number, and their names sorted.
    fn big(n: u32) -> (FakeCard, Vec<String>) {
        let mut c = FakeCard::new(&[]);
        let mut names = Vec::new();
        for i in 0..n {
            let name = format!("F{:03}.NC", (i * 37) % n);
            c.add("", &name, "", false, "");
            names.push(name);
        }
        names.sort();
        (c, names)
    }

    #[test]
    fn scrolling_one_row_at_a_time_and_jumping_both_ways_shows_the_sorted_list() {
        let (mut c, names) = big(40);
        let mut l = FileList::new();
        let window = |l: &FileList, first: u8| -> Vec<String> {
            (first..first + ROWS as u8).filter_map(|i| l.row(i)).map(|(t, _)| String::from_utf8(t.to_vec()).unwrap()).collect()
        };
        let want = |first: usize| names[first..(first + ROWS).min(names.len())].to_vec();
        let mut firsts: Vec<u8> = (0..=33).chain((0..33).rev()).collect();
        firsts.extend([20, 5, 30, 33, 0, 12, 11, 17, 3]);
        for first in firsts {
            l.refresh(&mut c, first);
            assert_eq!(l.count, 40);
            assert_eq!(window(&l, first), want(first as usize), "first {first}");
            let (n, _) = l.entry(&mut c, first + 2).unwrap();
            assert_eq!(n.as_str(), names[first as usize + 2]);
        }
    }

    #[test]
    fn no_card_lists_nothing() {
        let mut c = card();
        c.present = false;
        let mut l = FileList::new();
        l.refresh(&mut c, 0);
        assert_eq!((l.count, l.row(0)), (0, None));
    }
}
