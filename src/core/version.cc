#include "opl/core/version.h"

#include "opl_version_git.h"  // generated (cmake/OplVersion.cmake)

namespace opl {

std::string VersionNumber() { return OPL_VERSION_NUMBER; }

std::string GitDescribe() { return OPL_GIT_DESCRIBE; }

std::string VersionString() { return VersionNumber() + " (commit " + GitDescribe() + ")"; }

}  // namespace opl
