#pragma once
// A fatal signal (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT) prints its name and the stack, as
// module(+offset) frames that addr2line resolves against the same build, then ends the process
// with that signal as before. A crash on a machine we cannot debug on (a GPU host reached
// through scripts/gpu_run.sh, with no debugger) then says where it happened. SIGINT and SIGTERM
// remove the temporaries of unfinished atomic writes (engine/core/atomic_file.h) first.
namespace odvr::app {

void InstallCrashReport();

}  // namespace odvr::app
