// The glossy transfer's command-line pieces (cmd_glossy.cpp): `prtbake transport
// --transfer matrix` and `prtbake preview mesh --matrices|--cpca`, called from
// cmd_transport.cpp and cmd_preview.cpp.
#pragma once

#include <string>

#include "cli.h"
#include "prtbake/preview.h"

namespace prtbake::cli {

int runGlossyTransport(const CommandLine& cl);
int previewGlossyMesh(const CommandLine& cl, const std::string& input, const std::string& output);
// The mesh preview's --size WxH (or W: height 3/4 of it), --view and --rotate-light, into o
// (cmd_preview.cpp).
void meshViewFromCli(const CommandLine& cl, MeshPreviewOptions& o);

}  // namespace prtbake::cli
