// The version of OPL a program runs: the project's version number and the
// commit it was built from (`git describe --always --dirty`, read at build
// time; "unknown" outside a git checkout). Every tool prints it with
// --version (docs/cli.md).
//
//   opl::VersionNumber()  "0.1.0"
//   opl::VersionString()  "0.1.0 (commit 3177915abcde)"
//                         "0.1.0 (commit 3177915abcde-dirty)": uncommitted changes
#pragma once

#include <string>

namespace opl {

std::string VersionNumber();
std::string GitDescribe();
std::string VersionString();

}  // namespace opl
