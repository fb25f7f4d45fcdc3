# film.cmake — film's AOV table and image assembly (test_film_aovs).
pn_add_test(test_film_aovs)
