//! The menu's unit tests: the tree, the screens' text, and the state
//! machine driven as the encoder would.

use super::draw::wrapped;
use super::tree::ITEMS;
use super::*;
use crate::atc::Journal;
use crate::dollar;
use crate::machine::{Alarm, Machine, State};
use crate::ui::files::FileList;
use crate::ui::render::{Line, ROWS};
use crate::ui::sd::{Name, Outcome, Phase};
use crate::ui::text::Text;

fn screen(ui: &Ui, v: &View) -> Vec<String> {
    screen_of(ui, v, &Machine::new())
}

fn screen_of(ui: &Ui, v: &View, m: &Machine) -> Vec<String> {
    let files = FileList::for_test(ui.visible_files().0, v.files, |i| format!("FILE{i}.NC"));
    (0..ROWS)
        .map(|r| {
            let l = ui.line(r, v, m, &files);
            let s = String::from_utf8(l.chars.to_vec()).unwrap();
            if l.invert {
                format!("[{}]", s.trim_end())
            } else {
                s.trim_end().to_string()
            }
        })
        .collect()
}

#[test]
fn the_menu_tree_is_laid_out_as_the_spec_says() {
    assert_eq!(MenuId::Main.len(), 9);
    assert_eq!(MenuId::Main.item(1), (Text::RunFromSd, Act::Files));
    assert_eq!(MenuId::Main.item(8), (Text::Spindle, Act::SpindleMenu));
    assert_eq!(MenuId::Spindle.len(), 4);
    assert_eq!(MenuId::Spindle.item(3), (Text::OverrideShort, Act::SpindleOverride));
    assert_eq!(MenuId::Main.item(5), (Text::Tools, Act::ToolsMenu));
    assert_eq!(MenuId::Main.item(7), (Text::Info, Act::Info));
    assert_eq!(MenuId::Tools.len(), 9);
    assert_eq!(MenuId::Tools.item(8), (Text::CalibrateSetter, Act::CalibrateSetter));
    assert_eq!(MenuId::Jog.len(), 8);
    assert_eq!(MenuId::Jog.item(4), (Text::ZeroAxis, Act::ZeroAxis));
    assert_eq!(MenuId::Jog.item(5), (Text::ZeroAll, Act::ZeroAll));
    assert_eq!(MenuId::Jog.item(6), (Text::ProbeZ, Act::ProbeZ));
    assert_eq!(MenuId::Tools.item(5), (Text::ConfirmSpindle, Act::ConfirmSpindle));
    assert_eq!(MenuId::Tools.item(6), (Text::Changer, Act::Changer));
    assert_eq!(MenuId::Tools.item(7), (Text::ToolNumbers, Act::ToolNumbers));
    assert_eq!(MenuId::Job.item(2), (Text::Abort, Act::Abort));
    assert_eq!(MenuId::Home.item(4), (Text::HomeX, Act::HomeX));
}

#[test]
fn every_menu_entry_reads_back_as_a_text_and_an_action() {
    for [t, a] in ITEMS {
        assert!(Text::from_u8(t).is_some() && Act::from_u8(a).is_some(), "entry {t} {a}");
    }
    for b in 0..=255u8 {
        assert_eq!(Act::from_u8(b).map(|a| a as u8), (b <= Act::SpindleOverride as u8).then_some(b), "{b}");
    }
}

#[test]
fn status_screen_shows_state_position_feed_spindle_and_job() {
    let mut v = View::new();
    v.state = State::Run;
    v.wpos_um = [12_345, -5, 45_000];
    v.tool = 3;
    v.feed = 1200;
    v.override_pct = 90;
    v.rpm = 10300;
    v.job = Phase::Running;
    v.job_pct = 45;
    v.job_name = Name::parse(b"PART.NC").unwrap();
    let s = screen(&Ui::new(), &v);
    assert_eq!(s[0], "[ Run             T3]");
    assert_eq!(s[1], "X     12.345 mm");
    assert_eq!(s[2], "Y     -0.005 mm");
    assert_eq!(s[3], "Z     45.000 mm");
    assert_eq!(s[4], "F  1200 mm/min    90%");
    assert_eq!(s[5], "S 10300 rpm");
    assert_eq!(s[6], "PART.NC           45%");
    v.job = Phase::Ended(Outcome::BadLine(40));
    assert_eq!(screen(&Ui::new(), &v)[6], "Stopped: line 40");
    assert_eq!(screen(&Ui::new(), &v)[7], "Press for menu");
    // Why, when the job knows.
    v.job_why = Some(crate::gcode::interp::Error::SoftLimit.message());
    assert_eq!(screen(&Ui::new(), &v)[7], "target outside travel");
    v.job_why = Some(crate::gcode::interp::Error::BadFeed.message());
    assert_eq!(screen(&Ui::new(), &v)[7], "feed rate missing or");
    v.job_why = Some(crate::gcode::interp::Error::ProbeAlreadyTriggered.message());
    assert_eq!(screen(&Ui::new(), &v)[7], "probe input already", "cut at the last whole word");
}

#[test]
fn a_running_job_shows_its_time_and_the_time_left_by_the_cut() {
    let mut v = View::new();
    v.state = State::Run;
    v.job = Phase::Running;
    let row = |v: &View| screen(&Ui::new(), v)[7].clone();
    v.job_s = 125;
    v.job_pct = 25;
    assert_eq!(row(&v), "Time 2:05 Left 6:15");
    v.job_pct = 0;
    v.job_s = 5;
    assert_eq!(row(&v), "Time 0:05 Left -:--");
    v.job_s = 3700;
    v.job_pct = 50;
    assert_eq!(row(&v), "1:01:40 Left 1:01:40");
    v.job_pct = 100;
    assert_eq!(row(&v), "1:01:40 Left 0:00");
    // Held (an M0 in the job) or paused: the hint to resume comes first.
    v.state = State::Hold;
    assert_eq!(row(&v), "Press to resume");
    v.job = Phase::Paused;
    assert_eq!(row(&v), "Press to resume");
}

#[test]
fn status_screen_shows_the_host_message_and_progress_when_no_sd_job_runs() {
    let v = View::new();
    let mut m = Machine::new();
    assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "No job");
    m.host.set_message(b"Layer 3 of 10: roughing");
    assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "Layer 3 of 10: rough");
    m.host.pct = 7;
    assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "Layer 3 of 10: r   7%");
    m.host.set_message(b"");
    assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "                   7%".trim_end());
    // An SD job shows its own name and progress.
    let mut v = v;
    v.job = Phase::Running;
    v.job_pct = 45;
    v.job_name = Name::parse(b"PART.NC").unwrap();
    assert_eq!(screen_of(&Ui::new(), &v, &m)[6], "PART.NC           45%");
}

#[test]
fn choosing_a_file_asks_for_confirmation_then_runs_it() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.card_in = true;
    v.files = 3;
    assert_eq!(ui.step(0, true, &v), Cmd::None); // status -> menu
    assert_eq!(ui.step(1, true, &v), Cmd::ListFiles); // "Run from SD"
    assert_eq!(ui.screen, Screen::Files);
    assert_eq!(screen(&ui, &v)[1..4], ["[ < Back]", " FILE0.NC", " FILE1.NC"]);
    ui.step(2, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::ConfirmRun(1));
    assert_eq!(screen(&ui, &v)[0], "[ Run FILE1.NC?]");
    assert_eq!(ui.step(1, true, &v), Cmd::RunFile(1));
    assert_eq!(ui.screen, Screen::Status);
}

#[test]
fn a_folder_opens_in_place_and_back_goes_up_then_out() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.card_in = true;
    v.files = 3;
    v.folder_rows = 0b010; // entry 1 is a folder
    ui.go(Screen::Files);
    ui.step(2, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::OpenFolder(1));
    assert_eq!((ui.screen, ui.sel), (Screen::Files, 0));
    v.in_folder = true;
    v.folder_rows = 0;
    ui.step(1, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::ConfirmRun(0));
    ui.go(Screen::Files);
    assert_eq!(ui.step(0, true, &v), Cmd::FolderUp);
    assert_eq!(ui.screen, Screen::Files);
    v.in_folder = false;
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Main));
}

#[test]
fn a_long_file_list_scrolls_with_the_selection() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.card_in = true;
    v.files = 20;
    ui.go(Screen::Files);
    ui.step(9, false, &v);
    assert_eq!((ui.sel, ui.top), (9, 3));
    assert_eq!(ui.visible_files(), (2, 7));
    assert_eq!(screen(&ui, &v)[7], "[ FILE8.NC]");
    ui.step(100, false, &v);
    assert_eq!(ui.sel, 20);
    ui.step(-100, false, &v);
    assert_eq!((ui.sel, ui.top), (0, 0));
}

#[test]
fn abort_needs_a_confirmation_and_pause_turns_into_resume() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.job = Phase::Running;
    ui.go(Screen::Menu(MenuId::Job));
    assert_eq!(ui.step(1, true, &v), Cmd::Pause);
    v.job = Phase::Paused;
    assert_eq!(screen(&ui, &v)[2], "[ Resume]");
    assert_eq!(ui.step(0, true, &v), Cmd::Resume);
    ui.step(1, true, &v);
    assert_eq!(ui.screen, Screen::ConfirmAbort);
    assert_eq!(ui.step(0, true, &v), Cmd::None); // "No" is the default
    assert_eq!(ui.screen, Screen::Menu(MenuId::Job));
    ui.step(2, true, &v);
    assert_eq!(ui.step(1, true, &v), Cmd::Abort);
}

/// Optional stop (M1) is a Job-menu switch, the same
/// setting as `$152`.
#[test]
fn optional_stop_is_switched_in_the_job_menu() {
    let mut ui = Ui::new();
    let mut v = View::new();
    ui.go(Screen::Menu(MenuId::Job));
    assert_eq!(screen(&ui, &v)[5].trim_end(), " Opt. stop M1     off");
    assert_eq!(ui.step(4, true, &v), Cmd::OptionalStop(true));
    v.opt_stop = true;
    assert_eq!(screen(&ui, &v)[5], "[ Opt. stop M1      on]");
    assert_eq!(ui.step(0, true, &v), Cmd::OptionalStop(false));
}

#[test]
fn feed_override_is_set_in_steps_of_five() {
    let mut ui = Ui::new();
    let v = View::new();
    ui.go(Screen::Menu(MenuId::Job));
    ui.step(3, true, &v);
    assert_eq!(ui.screen, Screen::Override);
    ui.step(-4, false, &v);
    assert_eq!(screen(&ui, &v)[2], "          80%");
    assert_eq!(ui.step(0, true, &v), Cmd::Override(80));
}

#[test]
fn jogging_moves_by_the_step_per_detent_and_home_needs_idle() {
    let mut ui = Ui::new();
    let mut v = View::new();
    ui.go(Screen::Menu(MenuId::Jog));
    ui.step(1, true, &v); // axis X -> Y
    ui.step(1, true, &v); // step 1 -> 10 mm
    assert_eq!(screen(&ui, &v)[2..4], [" Axis Y", "[ Step 10 mm]"]);
    ui.step(1, true, &v); // jog now
    assert_eq!(ui.screen, Screen::Jogging);
    assert_eq!(ui.step(-2, false, &v), Cmd::Jog { axis: 1, delta_um: -20_000 });
    ui.step(0, true, &v);
    ui.go(Screen::Menu(MenuId::Home));
    v.state = State::Run;
    assert_eq!(ui.step(2, true, &v), Cmd::None);
    v.state = State::Idle;
    assert_eq!(ui.step(0, true, &v), Cmd::Home(0b100));
}

#[test]
fn info_and_settings_are_views() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.free_ram = 1234;
    ui.go(Screen::Info);
    let s = screen(&ui, &v);
    assert_eq!(s[4], " Free RAM 1234 B");
    ui.go(Screen::Settings);
    let s = screen(&ui, &v);
    assert_eq!(s[1..4], ["[ < Back]", " $3                 0", " $5                 0"], "{s:?}");
    ui.step(0, true, &v);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Main));
}

/// What the firmware does after each encoder step (`firmware.rs`).
fn edit_step(ui: &mut Ui, d: i8, press: bool, v: &View, m: &Machine) -> Cmd {
    let c = ui.step(d, press, v);
    if let Cmd::Edit(e) = c {
        ui.edit_um = e.current(m);
    }
    ui.fit_edit(m);
    c
}

#[test]
fn every_setting_is_listed_in_order_and_read_like_dollar_dollar() {
    let mut s = crate::config::Settings::default();
    let n: Vec<u8> = (0..dollar::count()).map(dollar::nth).collect();
    let listed: Vec<u8> = (0..=255).filter(|&k| dollar::field(&mut s, k).is_some()).collect();
    assert_eq!(n, listed);
    assert!(n.len() > 30, "{n:?}");
    let m = Machine::new();
    let mut ui = Ui::new();
    ui.go(Screen::Settings);
    let i = n.iter().position(|&k| k == 110).unwrap() as i8;
    ui.scroll(i + 1, dollar::count() + 1);
    let s = screen_of(&ui, &View::new(), &m);
    assert_eq!(s[7], format!("[ $110{:>16}]", format!("{:.3}", m.settings.max_feed_mm_per_min[0])), "{s:?}");
}

#[test]
fn a_setting_is_edited_with_the_encoder_and_stored_through_its_dollar_line() {
    let m = Machine::new();
    let v = View::new();
    let mut ui = Ui::new();
    ui.go(Screen::Settings);
    let i = (0..dollar::count()).position(|k| dollar::nth(k) == 170).unwrap() as i8;
    assert_eq!(edit_step(&mut ui, i + 1, true, &v, &m), Cmd::Edit(Edit::Setting(170)));
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0], "[ $170]");
    assert_eq!(s[1..4].join(" ").split_whitespace().collect::<Vec<_>>().join(" "), "tool change X1 (in front of the magazine), mm");
    assert_eq!(s[4..8], [" < Back", "[ Value         23.000]", " Step           1.000", " Save"], "{s:?}");
    // Press: the value turns; 7 detents of 1, then the step 0.1 (4
    // presses round from 1: 10, 100, 1000, 0.001 … 0.1) and 5 more.
    edit_step(&mut ui, 0, true, &v, &m);
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >        23.000]");
    edit_step(&mut ui, 7, true, &v, &m);
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value         30.000]");
    edit_step(&mut ui, 1, false, &v, &m);
    for _ in 0..6 {
        edit_step(&mut ui, 0, true, &v, &m);
    }
    assert_eq!(screen_of(&ui, &v, &m)[6], "[ Step           0.100]");
    edit_step(&mut ui, -1, true, &v, &m);
    edit_step(&mut ui, 5, true, &v, &m);
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value         30.500]");
    // Save: the line `$170=30.500`, the same as over serial.
    let c = edit_step(&mut ui, 2, true, &v, &m);
    assert_eq!(c, Cmd::Store(Edit::Setting(170), 30_500));
    let mut l = Line::blank();
    let n = Edit::Setting(170).gcode(30_500, None, &mut l);
    assert_eq!(&l.chars[..n], b"$170=30.500");
    assert_eq!(ui.screen, Screen::Reply(ToolOp::Store(Edit::Setting(170))));
    // The reply; a press goes back to the edit screen.
    ui.reply = Reply::Ok;
    edit_step(&mut ui, 0, true, &v, &m);
    assert_eq!(ui.screen, Screen::Edit(Edit::Setting(170), false));
    // Back: the list, on $170.
    edit_step(&mut ui, -1, true, &v, &m);
    assert_eq!(ui.screen, Screen::Settings);
    assert_eq!(dollar::nth(ui.sel - 1), 170);
}

#[test]
fn flags_and_masks_turn_within_their_range_in_whole_steps() {
    let m = Machine::new();
    let v = View::new();
    let mut ui = Ui::new();
    ui.go(Screen::Settings);
    // $5 (mask, 0..31).
    edit_step(&mut ui, 2, true, &v, &m);
    assert_eq!(ui.screen, Screen::Edit(Edit::Setting(5), false));
    edit_step(&mut ui, 0, true, &v, &m);
    edit_step(&mut ui, 40, false, &v, &m);
    assert_eq!(ui.edit_um, 31_000);
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >            31]");
    edit_step(&mut ui, -50, true, &v, &m);
    assert_eq!(ui.edit_um, 0);
    // The step goes 1, 10, 100, 1.
    edit_step(&mut ui, 1, false, &v, &m);
    for want in ["10", "100", "1"] {
        edit_step(&mut ui, 0, true, &v, &m);
        assert_eq!(screen_of(&ui, &v, &m)[6], format!("[ Step{want:>16}]"));
    }
}

#[test]
fn a_pockets_tool_number_is_edited_and_stored_as_g10_l1_lines() {
    let m = Machine::new();
    let v = View::new();
    let mut ui = Ui::new();
    tools_entry(&mut ui, &v, 7);
    assert_eq!(ui.screen, Screen::Numbers);
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0..3], ["[ Tool numbers]", "[ < Back]", " Pocket 1          T1"], "{s:?}");
    edit_step(&mut ui, 5, true, &v, &m);
    assert_eq!(ui.screen, Screen::Edit(Edit::Pocket(5), false));
    assert_eq!(screen_of(&ui, &v, &m)[0], "[ Pocket 5]");
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Value             T5]");
    edit_step(&mut ui, 0, true, &v, &m);
    edit_step(&mut ui, 15, true, &v, &m);
    assert_eq!(ui.edit_um, 20_000);
    edit_step(&mut ui, 2, false, &v, &m);
    assert_eq!(edit_step(&mut ui, 0, true, &v, &m), Cmd::Store(Edit::Pocket(5), 20_000));
    let line = |clear| {
        let mut l = Line::blank();
        let n = Edit::Pocket(5).gcode(20_000, clear, &mut l);
        String::from_utf8(l.chars[..n].to_vec()).unwrap()
    };
    assert_eq!(line(Some(5)), "G10 L1 P5 Q0");
    assert_eq!(line(None), "G10 L1 P20 Q5");
    // 0 reads "none"; no further than 254.
    let mut ui = Ui::new();
    ui.go(Screen::Numbers);
    edit_step(&mut ui, 1, true, &v, &m);
    edit_step(&mut ui, 0, true, &v, &m);
    edit_step(&mut ui, -3, false, &v, &m);
    assert_eq!(screen_of(&ui, &v, &m)[5], "[ Turn >          none]");
    ui.edit_step = 5;
    edit_step(&mut ui, 9, false, &v, &m);
    assert_eq!(ui.edit_um, 254_000);
}

/// Open the Tools menu from the status screen and press entry `i`.
#[test]
fn the_setter_is_calibrated_from_the_reference_tools_length_and_diameter() {
    let mut m = Machine::new();
    m.setter.ref_length_um = 40_000;
    let v = View::new();
    let mut ui = Ui::new();
    let c = tools_entry(&mut ui, &v, 8);
    assert_eq!(c, Cmd::Edit(Edit::RefLength));
    ui.edit_um = Edit::RefLength.current(&m);
    ui.fit_edit(&m);
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0], "[ Calibrate setter]");
    assert_eq!(s[1..4].join(" ").split_whitespace().collect::<Vec<_>>().join(" "), "Reference tool in the spindle: its length, mm");
    assert_eq!(s[5], "[ Value         40.000]");
    // 50.000 mm (10 detents of 1), saved: stored, then the diameter.
    edit_step(&mut ui, 0, true, &v, &m);
    edit_step(&mut ui, 10, true, &v, &m);
    assert_eq!(edit_step(&mut ui, 2, true, &v, &m), Cmd::Store(Edit::RefLength, 50_000));
    assert_eq!(ui.screen, Screen::Reply(ToolOp::Store(Edit::RefLength)));
    m.setter.ref_length_um = 50_000;
    ui.reply = Reply::Ok;
    assert_eq!(screen_of(&ui, &v, &m)[2], " Ref length    50.000");
    assert_eq!(edit_step(&mut ui, 0, true, &v, &m), Cmd::Edit(Edit::RefDia));
    assert_eq!(ui.screen, Screen::Edit(Edit::RefDia, false));
    // 6 mm; Save runs the calibration.
    edit_step(&mut ui, 0, true, &v, &m);
    edit_step(&mut ui, 6, true, &v, &m);
    assert_eq!(edit_step(&mut ui, 2, true, &v, &m), Cmd::Store(Edit::RefDia, 6_000));
    let mut l = Line::blank();
    let n = calibrate_line(50_000, 6_000, &mut l);
    assert_eq!(&l.chars[..n], b"G37 L50.000 R3.000");
    // The result: the beam's Z (user's, +Z up) and width; a press: Tools.
    m.setter.beam_z_um = 12_345;
    m.setter.beam_width_um = 1_500;
    ui.reply = Reply::Ok;
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[2..4], [" Beam Z       -12.345", " Beam width     1.500"], "{s:?}");
    edit_step(&mut ui, 0, true, &v, &m);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 8));
    // A refused length goes back to its edit, not on to the diameter.
    tools_entry(&mut ui, &v, 8);
    edit_step(&mut ui, 3, true, &v, &m);
    ui.reply = Reply::Err(Text::NotIdle.as_fstr());
    edit_step(&mut ui, 0, true, &v, &m);
    assert_eq!(ui.screen, Screen::Edit(Edit::RefLength, false));
}

#[test]
fn zero_x_y_z_zeroes_all_three_in_one_line() {
    let mut l = Line::blank();
    let n = ToolOp::Zero(ALL_AXES).gcode(&mut l);
    assert_eq!(&l.chars[..n], b"G10 L20 P0 X0 Y0 Z0");
    let mut ui = Ui::new();
    let mut v = View::new();
    ui.go(Screen::Menu(MenuId::Jog));
    assert_eq!(ui.step(5, true, &v), Cmd::Tool(ToolOp::Zero(ALL_AXES)));
    v.wpos_um = [0, 0, 0];
    ui.reply = Reply::Ok;
    let s = screen(&ui, &v);
    assert_eq!(s[0..5], ["[ Zero X Y Z]", "", " X              0.000", " Y              0.000", " Z              0.000"], "{s:?}");
    ui.step(0, true, &v);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Jog), 5));
}

fn tools_entry(ui: &mut Ui, v: &View, i: i8) -> Cmd {
    *ui = Ui::new();
    // The main menu (a press on the status screen, outside an alarm).
    ui.go(Screen::Menu(MenuId::Main));
    ui.step(5, true, v); // Tools
    assert_eq!(ui.screen, Screen::Menu(MenuId::Tools));
    ui.step(i, true, v)
}

#[test]
fn tools_menu_lists_change_measure_table_and_confirm() {
    let mut ui = Ui::new();
    let v = View::new();
    tools_entry(&mut ui, &v, 0);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Main), "< Back");
    assert_eq!(ui.sel, 5, "back on Tools");
    ui.step(0, true, &v);
    let s = screen(&ui, &v);
    assert_eq!(s[..7], ["[ Tools]", "[ < Back]", " Change tool", " Measure length", " Measure len+dia", " Tool table", " Confirm spindle"]);
}

#[test]
fn change_tool_picks_a_tool_asks_then_runs_t_n_and_shows_the_outcome() {
    let mut ui = Ui::new();
    let mut v = View::new();
    let mut m = Machine::new();
    v.tool = 3;
    m.atc.tools.spindle = 3;
    m.atc.tools.occupied &= !(crate::atc::tools::pocket_bit(3) | crate::atc::tools::pocket_bit(6));
    assert_eq!(tools_entry(&mut ui, &v, 1), Cmd::None);
    assert_eq!(ui.screen, Screen::PickTool(false));
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0], "[ Change tool]");
    assert_eq!(s[1..6], [" < Back", " T0 no tool", " T1", " T2", "[ T3 in spindle]"], "opens on the spindle tool");
    ui.step(3, false, &v);
    assert_eq!(screen_of(&ui, &v, &m)[7], "[ T6 pocket empty]");
    // T2: "Change to T2?", No goes back to the list on T2.
    ui.step(-4, true, &v);
    assert_eq!(ui.screen, Screen::AskTool(ToolOp::Change(2)));
    assert_eq!(screen(&ui, &v)[0..3], ["[ Change to T2?]", "[ No]", " Yes"]);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!((ui.screen, ui.sel), (Screen::PickTool(false), 3));
    ui.step(0, true, &v);
    assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Change(2)));
    assert_eq!((ui.screen, ui.reply), (Screen::Reply(ToolOp::Change(2)), Reply::Pending));
    // While it runs: the state; presses do nothing.
    v.state = State::Tool;
    assert_eq!(screen(&ui, &v)[0..3], ["[ Change tool]", "", " Tool change"]);
    assert_eq!(ui.step(1, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::Reply(ToolOp::Change(2)));
    // Done.
    v.state = State::Idle;
    v.tool = 2;
    ui.reply = Reply::Ok;
    let s = screen(&ui, &v);
    assert_eq!((s[2].as_str(), s[7].as_str()), (" T2 in spindle", "Press: back"));
    ui.step(0, true, &v);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 1));
}

#[test]
fn a_refused_change_shows_the_machine_error_word_wrapped() {
    let mut ui = Ui::new();
    let v = View::new();
    tools_entry(&mut ui, &v, 1);
    ui.step(1, true, &v);
    assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Change(1)));
    ui.reply = Reply::Err(crate::atc::Fault::PocketEmpty.message());
    let s = screen(&ui, &v);
    // "pocket of that tool is empty (M61 P<n> S1 if loaded)"
    assert_eq!(s[2..6], [" pocket of that tool", " is empty (M61 P<n>", " S1 if loaded)", ""]);
    let long = crate::gcode::interp::Error::NotHomed.message();
    ui.reply = Reply::Err(long);
    let s = screen(&ui, &v);
    assert_eq!(s[2..6], [" not homed: home", " (G28) or unlock", " (M999) first,", " nothing moved"]);
    // A word longer than a line is cut.
    let mut l = Line::blank();
    wrapped(F!("a abcdefghijklmnopqrstuvwxyz b"), 1, &mut l);
    assert_eq!(String::from_utf8(l.chars.to_vec()).unwrap(), " abcdefghijklmnopqrst");
    let mut l = Line::blank();
    wrapped(F!("a abcdefghijklmnopqrstuvwxyz b"), 2, &mut l);
    assert_eq!(String::from_utf8(l.chars.to_vec()).unwrap().trim_end(), " b");
}

#[test]
fn tool_commands_are_refused_while_the_machine_is_busy() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.state = State::Run;
    assert_eq!(tools_entry(&mut ui, &v, 2), Cmd::None);
    assert_eq!(ui.screen, Screen::Reply(ToolOp::Measure { diameter: false }));
    assert_eq!(screen(&ui, &v)[2], " Machine busy");
    v.state = State::Idle;
    v.job = Phase::Running;
    ui.step(0, true, &v);
    assert_eq!(ui.sel, 2, "back on Measure length");
    assert_eq!(ui.step(1, true, &v), Cmd::None, "measure during an SD job");
    // In alarm the machine itself answers (with the alarm).
    v.job = Phase::Idle;
    v.state = State::Alarm;
    assert_eq!(tools_entry(&mut ui, &v, 3), Cmd::Tool(ToolOp::Measure { diameter: true }));
}

#[test]
fn measuring_runs_g37_or_g37_d1_and_shows_the_table_entry() {
    let mut ui = Ui::new();
    let mut v = View::new();
    let mut m = Machine::new();
    v.tool = 4;
    m.atc.table.length_um[3] = 24_511;
    m.atc.table.diameter_um[3] = 1_590;
    assert_eq!(tools_entry(&mut ui, &v, 2), Cmd::Tool(ToolOp::Measure { diameter: false }));
    ui.reply = Reply::Ok;
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0..5], ["[ Measure length]", "", " T      L mm     D mm", " T4*  24.511    1.590", ""]);
    assert_eq!(tools_entry(&mut ui, &v, 3), Cmd::Tool(ToolOp::Measure { diameter: true }));
    ui.reply = Reply::Ok;
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0..4], ["[ Measure len+dia]", "", " T      L mm     D mm", " T4*  24.511    1.590"]);
    ui.step(0, true, &v);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 3));
}

#[test]
fn tool_ops_are_the_gcode_lines_of_the_serial_commands() {
    let line = |op: ToolOp| {
        let mut l = Line::blank();
        let n = op.gcode(&mut l);
        String::from_utf8(l.chars[..n].to_vec()).unwrap()
    };
    assert_eq!(line(ToolOp::Change(2)), "M6 T2");
    assert_eq!(line(ToolOp::Change(12)), "M6 T12");
    assert_eq!(line(ToolOp::Measure { diameter: false }), "G37");
    assert_eq!(line(ToolOp::Measure { diameter: true }), "G37 D1");
    assert_eq!(line(ToolOp::Confirm(0)), "M61 Q0");
    for t in 0..=12u8 {
        let g = line(ToolOp::Change(t));
        let l = crate::gcode::parse(g.as_bytes()).unwrap();
        assert_eq!(l.tool(), Some(t));
    }
}

#[test]
fn the_tool_table_scrolls_through_t1_to_t12() {
    let mut ui = Ui::new();
    let mut v = View::new();
    let mut m = Machine::new();
    v.tool = 3;
    m.atc.table.length_um[2] = 25_000;
    m.atc.table.diameter_um[2] = 2_000;
    m.atc.table.length_um[11] = 105_250;
    tools_entry(&mut ui, &v, 4);
    assert_eq!(ui.screen, Screen::ToolTable);
    let s = screen_of(&ui, &v, &m);
    assert_eq!(s[0], "[ T      L mm     D mm]");
    assert_eq!(s[1], " T1    0.000    0.000");
    assert_eq!(s[3], " T3*  25.000    2.000");
    assert_eq!(s[7], " T7    0.000    0.000");
    ui.step(100, false, &v);
    let s = screen_of(&ui, &v, &m);
    assert_eq!((s[1].as_str(), s[7].as_str()), (" T6    0.000    0.000", " T12 105.250    0.000"));
    ui.step(-1, false, &v);
    assert_eq!(screen_of(&ui, &v, &m)[1], " T5    0.000    0.000");
    ui.step(0, true, &v);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Tools), 4));
}

#[test]
fn confirm_spindle_works_only_after_an_interrupted_change_and_sends_m61() {
    let mut ui = Ui::new();
    let mut v = View::new();
    // Nothing interrupted: it says so.
    assert_eq!(tools_entry(&mut ui, &v, 5), Cmd::None);
    let s = screen(&ui, &v);
    assert_eq!(s[0..4], ["[ Confirm spindle]", "", " No interrupted tool", " change"]);
    // Interrupted T2 -> T5: the status screen says so.
    v.interrupted = Some(Journal { from: 2, to: 5 });
    let s = screen(&Ui::new(), &v);
    assert_eq!(s[6..8], ["Change interrupted:", "Tools>Confirm spindle"]);
    ui.step(0, true, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::PickTool(true));
    let s = screen(&ui, &v);
    assert_eq!(s[0..5], ["[ In spindle now?]", "[ < Back]", " T0 no tool", " T1", " T2 old tool"]);
    assert_eq!(s[7], " T5 new tool");
    ui.step(1, true, &v);
    assert_eq!(screen(&ui, &v)[0], "[ Spindle holds T0?]");
    assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Confirm(0)));
    assert_eq!(ui.screen, Screen::Reply(ToolOp::Confirm(0)));
    // In alarm (M112 mid-change) the confirmation still goes to the machine.
    v.state = State::Alarm;
    tools_entry(&mut ui, &v, 5);
    ui.step(3, true, &v);
    assert_eq!(ui.step(1, true, &v), Cmd::Tool(ToolOp::Confirm(2)));
}

#[test]
fn in_an_alarm_the_status_screen_names_it_and_a_press_opens_the_way_out() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.state = State::Alarm;
    v.alarm = Some(Alarm::HardLimit);
    v.limit_axes = 0b001;
    let s = screen(&ui, &v);
    assert_eq!(s[0], "[ ALARM           T0]");
    assert_eq!(s[5], "Hard limit X");
    assert_eq!(s[7], "Press to recover");
    v.limit_axes = 0b110;
    assert_eq!(screen(&ui, &v)[5], "Hard limit YZ");
    v.alarm = Some(Alarm::ProbeFailed);
    assert_eq!(screen(&ui, &v)[5], "Probe missed");
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Alarm));
    assert_eq!(screen(&ui, &v)[..6], ["[ Alarm]", "[ Status]", " Unlock", " Home all", " Jog", " Confirm spindle"]);
    // Unlock: back on the status screen.
    assert_eq!(ui.step(1, true, &v), Cmd::Unlock);
    assert_eq!(ui.screen, Screen::Status);
    // Home all homes from the alarm.
    ui.step(0, true, &v);
    assert_eq!(ui.step(2, true, &v), Cmd::Home(0b111));
    // Jog unlocks and opens the Jog menu.
    ui.step(0, true, &v);
    assert_eq!(ui.step(3, true, &v), Cmd::Unlock);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Jog));
    // Confirm spindle opens the tool list.
    ui.go(Screen::Status);
    v.interrupted = Some(Journal { from: 1, to: 2 });
    ui.step(0, true, &v);
    ui.step(4, true, &v);
    assert_eq!(ui.screen, Screen::PickTool(true));
    // < Status goes back.
    ui.go(Screen::Status);
    ui.step(0, true, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::Status);
}

#[test]
fn a_card_pulled_mid_job_shows_the_line_it_stopped_at() {
    let ui = Ui::new();
    let mut v = View::new();
    v.state = State::Hold;
    v.job = Phase::Aborting(Outcome::CardRemoved(41));
    let s = screen(&ui, &v);
    assert_eq!(s[6], "Card out: line 41");
    assert_eq!(s[7], "Press for menu", "no resume offered");
    v.state = State::Idle;
    v.job = Phase::Ended(Outcome::CardRemoved(41));
    assert_eq!(screen(&ui, &v)[6], "Card out: line 41");
}

#[test]
fn the_spindle_menu_switches_sets_the_speed_and_the_override_and_leaves_a_job_s_spindle_alone() {
    let mut ui = Ui::new();
    let mut v = View::new();
    v.speed = 8000;
    ui.go(Screen::Menu(MenuId::Main));
    ui.step(8, false, &v);
    ui.step(0, true, &v);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Spindle));
    // On at the speed in force; off again.
    ui.step(1, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::Spindle { on: true, rpm: 8000, set: false });
    v.rpm = 8000;
    assert_eq!(ui.step(0, true, &v), Cmd::Spindle { on: false, rpm: 8000, set: false });
    // Speed: 100 rpm a detent, kept on.
    ui.step(1, false, &v);
    ui.step(0, true, &v);
    assert_eq!(ui.screen, Screen::SpindleSpeed);
    ui.step(-30, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::Spindle { on: true, rpm: 5000, set: true });
    // Override: 10 % a detent within 10..200.
    ui.step(1, false, &v);
    ui.step(0, true, &v);
    assert_eq!(ui.screen, Screen::SpindleOverride);
    ui.step(50, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::SpindleOverride(200));
    // During a job, on/off and speed are the job's; the override is not.
    v.job = Phase::Running;
    ui.step(-2, false, &v);
    assert_eq!(ui.step(0, true, &v), Cmd::None);
    assert_eq!(ui.screen, Screen::Menu(MenuId::Spindle));
    // Back returns to the main menu on Spindle.
    ui.step(-5, false, &v);
    ui.step(0, true, &v);
    assert_eq!((ui.screen, ui.sel), (Screen::Menu(MenuId::Main), 8));
}
