// layertrace — the command-line tool (src/layertrace/app/cli.h).
#include "layertrace/app/cli.h"

int main(int argc, char** argv) { return lt::runCli(argc, argv); }
