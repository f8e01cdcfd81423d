"""Work on recorded drive logs: replay of logged voltages through the machine model, observers run offline
on logs, and the synthetic logs (with measurement noise) they are tested and tuned on."""
