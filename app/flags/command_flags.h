#pragma once
// The command-line pieces every `odvr` command and `odvr bench` program shares: how a command is
// run, on/off flags, finite numbers in a range, the cone counts.
#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace odvr::app {

// What a command's Add<X>(sub) returns once it has declared its options: the function that runs
// it, returning the process exit code.
using CommandFn = std::function<int()>;

// A flag that sets *value to `set_to`. Where CLI11's "!--flag" form prints "--flag{false}" in
// --help, this reads as the plain flag it is; a switch with an on and an off name is two of them.
CLI::Option* AddSetFlag(CLI::App* sub, const std::string& name, bool* value, bool set_to, const std::string& help);

// A command-line number in [min, max], finite: CLI::Range lets "nan" through (every comparison with
// it is false), and a value the command then took for "not given" used to pass silently.
CLI::Validator FiniteNumberIn(double min, double max);

// A comma-separated list of finite numbers ("1,2.5,-3"); throws UsageError naming `flag` and the
// item that is not one.
std::vector<double> ParseNumberList(const std::string& text, const std::string& flag);

// --cones (1, 7, 19 or 37) as the renderer's hexagonal rings (0-3); throws UsageError otherwise.
int ConeRingsForCount(int cones);

}  // namespace odvr::app
