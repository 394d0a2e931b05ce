#pragma once
// A fatal signal (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT) prints its name and the stack, as
// module(+offset) frames that addr2line resolves against the same build, then ends the process
// with that signal as before. A crash on a machine we cannot debug on (a GPU host reached
// through scripts/gpu_run.sh, with no debugger) then says where it happened.
namespace odvr::app {

void InstallCrashReport();
// SIGINT, SIGTERM, SIGHUP and SIGQUIT remove the temporaries of unfinished atomic writes, then end
// the process by the signal; SIGXFSZ is ignored, so a write past the file size limit fails (EFBIG)
// like one on a full disk. Installed in every build (the crash report is left to a sanitizer where
// there is one).
void InstallInterruptCleanup();

}  // namespace odvr::app
