#pragma once
// Defaults that live in the repository (the CMU clips in data/mocap/cmu, the shipped model in
// models/pretrained) are found when the program runs, not compiled in: a binary built in one
// checkout and run from another folder, or copied elsewhere, must not depend on where it was built.
#include <string>

namespace amt::app {

/// The folder `relative` of the repository ("data/mocap/cmu"), looked up first in every folder
/// above the running program (a build inside a checkout, <checkout>/build/app/amt, finds
/// <checkout>/data/mocap/cmu), then in the current folder. Returns its absolute path, or "" when
/// neither has it.
std::string find_repository_folder(const std::string& relative);

/// find_repository_folder(relative) for the default of `option`, or amt::Error when it is not
/// found: "<option>: no default: <relative> is neither above the amt program (<exe>) nor in the
/// current folder (<cwd>); pass <option> <what>".
std::string repository_default(const std::string& relative, const std::string& option, const std::string& what);

/// The --help sentence of such a default, with the folder this run finds: "Default: the
/// repository's <relative>, looked up above the amt program, then in the current folder (here: ...)".
std::string repository_default_help(const std::string& relative);

}  // namespace amt::app
