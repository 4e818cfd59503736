// fbar's main: hands the command line to the front end (cli.h), which loads the scene and runs it.
#include "cli.h"

int main(int argc, char** argv) { return fbar::cli_main(argc, argv); }
