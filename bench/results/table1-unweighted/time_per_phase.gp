# time_per_phase.png from time_per_phase.csv (written by fillgs); re-plot with: gnuplot time_per_phase.gp
set terminal pngcairo size 640,480 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'time_per_phase.png'
set title 'mean seconds per phase and run'
set xlabel ''
set ylabel 'seconds'
set key off
set xtics rotate by -45 left scale 0 ('select' 0, 'refine' 1, 'weights' 2, 'train' 3, 'eval' 4)
set xrange [-0.6:4.6]
set yrange [*<0:*]
set offsets 0, 0, graph 0.08, 0
set boxwidth 0.7
plot 'time_per_phase.csv' skip 1 using 0:2 with boxes lc rgb '#3c78b4', '' skip 1 using 0:2:3 with labels offset 0,0.7 font ',9'
