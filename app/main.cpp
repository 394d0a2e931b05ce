#include "app/commands.h"

int main(int argc, char** argv) { return odvr::app::Main(argc, argv); }
