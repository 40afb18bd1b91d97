// The glossy transfer's command-line pieces (cmd_glossy.cpp): `prtbake transport
// --transfer matrix` and `prtbake preview mesh --matrices|--cpca`, called from
// cmd_transport.cpp and cmd_preview.cpp.
#pragma once

#include <string>

#include "cli.h"

namespace prtbake::cli {

int runGlossyTransport(const CommandLine& cl);
int previewGlossyMesh(const CommandLine& cl, const std::string& input, const std::string& output);

}  // namespace prtbake::cli
