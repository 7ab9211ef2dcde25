// layertrace — the command-line tool (src/layertrace/app/cli.h), with the interactive viewer
// (apps/viewer/) when the build has GLFW, OpenGL and Dear ImGui.
#include "layertrace/app/cli.h"

#if LAYERTRACE_HAS_VIEWER
namespace lt {
int runViewer(const ViewOptions& options);
}
#endif

int main(int argc, char** argv) {
#if LAYERTRACE_HAS_VIEWER
  lt::setViewRunner(&lt::runViewer);
#endif
  return lt::runCli(argc, argv);
}
