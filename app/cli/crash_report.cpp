#include "app/cli/crash_report.h"

#include <execinfo.h>
#include <signal.h>
#include <unistd.h>

#include <cstring>
#include <initializer_list>

#include "core/atomic_file.h"

namespace odvr::app {
namespace {

void Write(const char* text) {
  // Nothing to do if stderr is gone; the signal is re-raised either way.
  [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, text, std::strlen(text));
}

const char* SignalName(int sig) {
  switch (sig) {
    case SIGSEGV:
      return "SIGSEGV";
    case SIGBUS:
      return "SIGBUS";
    case SIGFPE:
      return "SIGFPE";
    case SIGILL:
      return "SIGILL";
    case SIGABRT:
      return "SIGABRT";
    default:
      return "signal";
  }
}

void OnFatalSignal(int sig) {
  // Only async-signal-safe calls: write, backtrace (warmed up at install, so it does not load
  // libgcc_s here), backtrace_symbols_fd (no malloc).
  char number[16];
  int len = 0;
  for (int v = sig; v > 0 && len < 15; v /= 10) number[len++] = static_cast<char>('0' + v % 10);
  char line[96] = "odvr: fatal signal ";
  std::size_t at = std::strlen(line);
  while (len > 0) line[at++] = number[--len];
  line[at] = '\0';
  Write(line);
  Write(" (");
  Write(SignalName(sig));
  Write("); stack (module(+offset), resolve with addr2line -f -C -e MODULE OFFSET):\n");
  void* frames[64];
  const int n = backtrace(frames, 64);
  backtrace_symbols_fd(frames, n, STDERR_FILENO);
  // SA_RESETHAND restored the default action: the process ends with the signal it got.
  raise(sig);
}

// SIGINT, SIGTERM, SIGHUP (the terminal closed), SIGQUIT: the temporaries of unfinished atomic
// writes go, then the default action, so the process still ends by the signal. While an output
// set is being swapped into place (InterruptsDeferred) the signal is held until the swap is done.
void OnInterrupt(int sig) {
  if (!DeferInterrupt(sig)) EndByInterrupt(sig);
}

}  // namespace

void InstallCrashReport() {
  void* warm[1];
  backtrace(warm, 1);
  struct sigaction action {};
  action.sa_handler = OnFatalSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND | SA_NODEFER;
  for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) sigaction(sig, &action, nullptr);
}

void InstallInterruptCleanup() {
  struct sigaction interrupt {};
  interrupt.sa_handler = OnInterrupt;
  sigemptyset(&interrupt.sa_mask);
  // A signal ignored when odvr started (nohup, a background job) stays ignored.
  for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
    struct sigaction before {};
    if (sigaction(sig, nullptr, &before) == 0 && before.sa_handler == SIG_IGN) continue;
    sigaction(sig, &interrupt, nullptr);
  }
  // A write past the file size limit (ulimit -f) would kill the process with SIGXFSZ and leave its
  // temporary behind; ignored, the write fails with EFBIG and takes the normal error path: the
  // temporary removed, the old file kept, a message naming the output and a non-zero exit.
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  sigaction(SIGXFSZ, &ignore, nullptr);
}

}  // namespace odvr::app
