//! Every string of the UI and of the SD commands, in flash (see
//! [`super::flash`]): display labels, menu entries and serial messages.

crate::flash_texts! {
    // Serial prefixes and messages (Marlin's wording where Marlin has one).
    Echo = "echo:",
    Error = "Error:",
    BeginFileList = "Begin file list",
    EndFileList = "End file list",
    FileOpened = "File opened: ",
    SizeWord = " Size: ",
    FileSelected = "File selected",
    OpenFailed = "open failed, File: ",
    WritingToFile = "Writing to file: ",
    DoneSaving = "Done saving file.",
    SdPrintingByte = "SD printing byte ",
    NotSdPrinting = "Not SD printing",
    AtSdByte = " at SD byte ",
    JobStopped = "; job stopped at line ",
    MsgCardOk = "SD card ok",
    MsgSdInitFail = "SD init fail",
    MsgNoMedia = "No media",
    MsgCardReleased = "SD card released",
    MsgCardRemovedAt = "SD card removed: job stopped at line ",
    MsgCardEnded = "SD job ended (card removed), tool retracted, spindle off; stopped at line ",
    MsgAborted = "SD job aborted",
    MsgStoppedAtLine = "SD job stopped at line ",
    MsgEndedAtLine = "SD job ended with an error at line ",
    MsgReadErrorAt = "SD job ended: read error at byte ",
    MsgDonePrinting = "Done printing file",
    // Errors. The card's carry one of the words OctoPrint files under SD
    // card errors ("cannot open", "volume.init", "open failed"): it logs
    // those instead of disconnecting.
    ErrNoCard = "no SD card: cannot open files",
    ErrNoFs = "volume.init failed: no FAT16/FAT32 volume on the SD card",
    ErrNotFound = "open failed: file not found",
    ErrRead = "SD read error",
    ErrWrite = "SD write error",
    ErrBadName = "not an 8.3 file name",
    ErrNoFileSelected = "no SD file selected",
    ErrSeek = "M26 needs S<byte> within the file",
    ErrJobRunning = "SD job running",
    ErrLineTooLong = "line too long (max 256 characters)",
    ErrBinary = "binary data in file",
    // Machine states on the display.
    StIdle = "Idle",
    StNotHomed = "Not homed",
    StRun = "Run",
    StHold = "Hold",
    StAlarm = "ALARM",
    StHoming = "Homing",
    StTool = "Tool change",
    StProbe = "Probing",
    // Status screen.
    MmMin = "mm/min",
    Rpm = "rpm",
    Off = "off",
    NoJob = "No job",
    JobDone = "Done",
    JobPaused = "Paused",
    JobAborted = "Aborted",
    JobCardOut = "Card out: line ",
    JobCardStop = "Card out: retract",
    JobLine = "Stopped: line ",
    TimeLabel = "Time ",
    LeftLabel = " Left ",
    JobReadErr = "Read error",
    JobStopping = "Stopping",
    HintMenu = "Press for menu",
    HintResume = "Press to resume",
    HintRecover = "Press to recover",
    HintJog = "Turn: jog Press: done",
    HintEdit = "Turn: set Press: ok",
    // Alarms on the status screen, and the menu that gets out of one.
    AlHardLimit = "Hard limit",
    AlProbe = "Probe missed",
    AlEstop = "Emergency stop",
    AlHoming = "Homing failed",
    AlWatchdog = "Watchdog reset",
    AlCarousel = "Carousel not found",
    AlBrokenTool = "Broken tool",
    AlResetMoving = "Reset while moving",
    AlarmMenu = "Alarm",
    Unlock = "Unlock",
    // Menus.
    MainMenu = "Menu",
    Back = "< Back",
    Status = "Status",
    RunFromSd = "Run from SD",
    Job = "Job",
    Jog = "Jog",
    Home = "Home",
    Settings = "Settings",
    Info = "Info",
    Pause = "Pause",
    Resume = "Resume",
    Abort = "Abort",
    FeedOverride = "Feed override",
    Spindle = "Spindle",
    SpindleSpeed = "Speed",
    SpindleOverride = "Spindle override",
    OverrideShort = "Override",
    OptStop = "Opt. stop M1",
    On = " on",
    Axis = "Axis",
    Step = "Step",
    JogNow = "Jog now",
    HomeAll = "Home all",
    HomeZ = "Home Z",
    HomeY = "Home Y",
    HomeX = "Home X",
    RunQ = "Run ",
    AbortQ = "Abort the job?",
    Yes = "Yes",
    No = "No",
    NoCard = "No card",
    NoFiles = "No files",
    Files = "Files",
    Version = "Version ",
    FirmwareName = "MillFW",
    FreeRam = "Free RAM ",
    Bytes = " B",
    SdCard = "SD ",
    CardIn = "card in",
    CardOut = "no card",
    Mm = " mm",
    Pct = "%",
    NotIdle = "Machine busy",
    // Tools menu (docs/SPEC.md §7, §8).
    Tools = "Tools",
    ChangeTool = "Change tool",
    MeasureLength = "Measure length",
    MeasureDia = "Measure len+dia",
    ToolTable = "Tool table",
    ConfirmSpindle = "Confirm spindle",
    InSpindleQ = "In spindle now?",
    ChangeToQ = "Change to T",
    HoldsQ = "Spindle holds T",
    TableHead = "T      L mm     D mm",
    NoTool = "no tool",
    InSpindle = "in spindle",
    PocketEmpty = "pocket empty",
    OldTool = "old tool",
    NewTool = "new tool",
    NoChangeCut = "No interrupted tool change",
    ChangeCut = "Change interrupted:",
    HintConfirm = "Tools>Confirm spindle",
    HintBack = "Press: back",
    // Jog menu: work zero.
    ZeroAxis = "Zero",
    ZeroAll = "Zero X Y Z",
    ProbeZ = "Probe Z zero",
    WorkSystem = "Work G5",
    LineZero = "G10 L20 P0 ",
    LineZeroAll = "G10 L20 P0 X0 Y0 Z0",
    // Tools > Changer: the station's points, and teaching one.
    Changer = "Changer",
    TeachQ = "Teach ",
    PointX1 = "X1",
    PointYA = "Y point A",
    PointYB = "Y point B",
    PointZ1 = "Z1",
    PointZ2 = "Z2",
    PointTravel = "Travel Z",
    // Lines the Tools menu runs (Machine::run_menu_line).
    LineG37D1 = "G37 D1",
    LineM61Q = "M61 Q",
    // Settings and tool numbers: the edit screen.
    ToolNumbers = "Tool numbers",
    Pocket = "Pocket ",
    NoNumber = "none",
    NumberHelp = "Tool number kept in this pocket (0: none)",
    Value = "Value",
    TurnToSet = "Turn >",
    Save = "Save",
    LineG10L1P = "G10 L1 P",
    // Run from line: the Run screen's entry, its edit screen, the scan.
    FromLine = "From line",
    LineWord = "Line",
    Start = "Start",
    FromLineHelp = "Proposed: the last line reached by its last run",
    NoteFileChanged = "File changed since its last run: line 1",
    NoteNoRun = "No stopped run of this file: line 1",
    JobScanning = "Scan to ",
    JobNotResumed = "Not resumed: ",
    WhyPastEnd = "File ends before it",
    WhyCardOut = "Card out during scan",
    MsgPastEnd = "run from line: the file ends at line ",
    MsgNothingMoved = ", nothing moved",
    MsgNotResumed = "run from line not started: line ",
    MsgResumeAt = "run from line ",
    // Tools > Calibrate setter: the reference tool, then G37 L R.
    CalibrateSetter = "Calibrate setter",
    RefLengthHelp = "Reference tool in the spindle: its length, mm",
    RefDiaHelp = "Its diameter, mm. Save: measure it in the beam",
    RefLength = "Ref length",
    BeamZ = "Beam Z",
    BeamWidth = "Beam width",
    LineG37L = "G37 L",
    LineR = " R",
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: Text) -> String {
        let mut v = Vec::new();
        t.for_each(|b| v.push(b));
        String::from_utf8(v).unwrap()
    }

    #[test]
    fn every_hint_fits_on_its_line() {
        let hints = [Text::HintMenu, Text::HintResume, Text::HintRecover, Text::HintJog, Text::HintEdit, Text::HintConfirm, Text::HintBack];
        for t in hints {
            assert!(t.len() <= crate::ui::render::COLS, "{t:?}: {:?} is cut at {} characters", s(t), crate::ui::render::COLS);
        }
    }

    #[test]
    fn texts_come_back_whole_and_ascii() {
        assert_eq!(s(Text::Echo), "echo:");
        assert_eq!(s(Text::NotIdle), "Machine busy");
        assert_eq!(Text::Yes.len(), 3);
        assert_eq!(Text::Yes.byte(1), b'e');
        assert_eq!(Text::from_u8(TEXT_COUNT as u8), None);
        for i in 0..TEXT_COUNT as u8 {
            let t = Text::from_u8(i).unwrap();
            assert!(s(t).bytes().all(|b| (0x20..0x7F).contains(&b)), "{t:?}");
        }
    }
}
