list(APPEND PN_SOURCES src/shade/bsdf.c src/shade/bounds.c)
