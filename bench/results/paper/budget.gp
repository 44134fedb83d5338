# budget.png from budget.csv (written by fillgs); re-plot with: gnuplot budget.gp
set terminal pngcairo size 960,600 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'budget.png'
set title 'FillGS: PSNR against trajectories (3 rounds)'
set xlabel 'trajectories in all'
set ylabel 'PSNR (dB)'
set lmargin at screen 0.09
set rmargin at screen 0.74
set bmargin at screen 0.12
set tmargin at screen 0.9
set key outside right top vertical Left reverse noautotitle
set grid xtics ytics lc rgb '#dddddd' lt 1
set xrange [-0.42:63.42]
set yrange [12.645604:19.154596]
plot 'budget.csv' skip 1 using 2:($1 == 0 ? $3 : NaN) with linespoints pt 7 ps 1.1 lw 1.5 lc rgb '#3c78b4' title 'interpolation', \
     'budget.csv' skip 1 using 2:($1 == 1 ? $3 : NaN) with linespoints pt 7 ps 1.1 lw 1.5 lc rgb '#d62728' title 'extrapolation'
