set(PN_CLI_SOURCES src/cli/main.c)
