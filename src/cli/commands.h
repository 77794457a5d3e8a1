// Subcommands defined outside main.cc, one file each, registered in main.cc's table.
#pragma once

int RunFit(int argc, char** argv);
