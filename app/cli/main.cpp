#include "app/cli/commands.h"
#include "app/cli/crash_report.h"

int main(int argc, char** argv) {
  odvr::app::InstallInterruptCleanup();
#ifndef __SANITIZE_ADDRESS__  // the sanitizer's own report says more
  odvr::app::InstallCrashReport();
#endif
  return odvr::app::Main(argc, argv);
}
