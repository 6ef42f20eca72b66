// Private to src/io: the module design reader applied to an already parsed
// JSON value, for documents that embed a design (the scene JSON's "module").
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "opl/core/status.h"
#include "opl/sim/module_design.h"

namespace opl {

// Reads a design object as ReadModuleDesignJson does, except that "format"
// and "version" may be omitted (they are checked when present). Messages are
// "<name_for_messages>: <field_path>.<path in the design>: <what>"; relative
// pattern files are resolved against `base_dir`.
Result<ModuleDesign> ParseModuleDesignValue(const nlohmann::json& value,
                                            const std::string& name_for_messages,
                                            const std::string& field_path,
                                            const std::string& base_dir);

}  // namespace opl
