set(PN_CLI_SOURCES src/cli/main.c src/cli/util.c src/cli/options.c src/cli/report.c src/cli/render_cmd.c
    src/cli/inspect.c src/cli/ies2gonio.c src/cli/illuminance.c
    src/cli/merge.c)
