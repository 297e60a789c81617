"""Everything that speaks to or runs on a KR C4: the KUKAVARPROXY protocol and client (:mod:`.kvp`),
capture over it (:mod:`.kvp_capture`), the virtual controller's KUKAVARPROXY server
(:mod:`.server`), and the KRL programs (:mod:`.krl` excitation, :mod:`.krl_logger`,
:mod:`.krl_follower`). The only package of kukaid that opens sockets."""
